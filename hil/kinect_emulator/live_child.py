"""Entry point of LiveKinect's renderer child process: `python -m kinect_emulator.live_child`.

A module of its own so that `kinect_emulator.live` (imported by the package) is not also run as
__main__. The protocol (configuration pickle, then fixed-size requests on stdin) is in live.py.
"""

from kinect_emulator.live import _child_main

if __name__ == "__main__":
    raise SystemExit(_child_main())
