"""Camera faults for the soak: blank and malformed frames from the Kinect, requested while flying.

The live Kinect (kinect_emulator.live.LiveKinect) renders in a child process and takes its blank
frames from KinectOptions.blank_frames, fixed when it starts. A soak decides when the camera fails
only as the missions unfold, so `FaultyLiveKinect` runs the same child through
`soak.kinect_fault_child`, which reads fault requests from a file in the dump folder:

    <kind> <t_mono_s> <frames>      kind: blank | malformed

meaning: the next `frames` frames requested at or after `t_mono_s` (CLOCK_MONOTONIC, the pump's
request time) are delivered as `kind`. A blank frame is all zero (the renderer's own blank frame);
a malformed one is what a USB transfer with lost isochronous packets delivers: a band of rows of
garbage depth (random 11-bit values, some beyond the Kinect's range) and garbage colour, the rest of
the frame intact. Nothing else of the renderer changes, so the frames' records still match the
streamer's stamps.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from kinect_emulator import live as live_module
from kinect_emulator.live import LiveKinect

FAULTS_FILE_NAME = "camera-faults.txt"
FAULTS_ENV = "HIL_SOAK_CAMERA_FAULTS"  # the child reads the request file named here
CAMERA_FAULT_KINDS = ("blank", "malformed")
CHILD_MODULE = "soak.kinect_fault_child"


class FaultyLiveKinect(LiveKinect):
    """A LiveKinect whose renderer child also delivers requested blank / malformed frames."""

    def start(self) -> None:
        self.faults_path = Path(self.dir) / FAULTS_FILE_NAME
        self.dir.mkdir(parents=True, exist_ok=True)
        self.faults_path.write_text("")
        real_popen = subprocess.Popen
        faults_path = str(self.faults_path)

        def popen(argv, *args, **kwargs):
            # LiveKinect.start's one child: the same interpreter, another entry module.
            if list(argv[1:]) == ["-m", "kinect_emulator.live_child"]:
                argv = [argv[0], "-m", CHILD_MODULE]
                env = dict(kwargs.get("env") or os.environ)
                env[FAULTS_ENV] = faults_path
                kwargs["env"] = env
            return real_popen(argv, *args, **kwargs)

        live_module.subprocess.Popen = popen
        try:
            super().start()
        finally:
            live_module.subprocess.Popen = real_popen

    def inject(self, kind: str, t_mono_s: float, frames: int) -> None:
        """The next `frames` frames requested at or after t_mono_s are delivered as `kind`."""
        if kind not in CAMERA_FAULT_KINDS:
            raise ValueError(f"camera fault kind must be one of {CAMERA_FAULT_KINDS}, not {kind!r}")
        if frames < 1:
            raise ValueError("frames must be >= 1")
        with open(self.faults_path, "a") as f:
            f.write(f"{kind} {t_mono_s:.6f} {int(frames)}\n")

    def fault_frames(self) -> dict[str, int]:
        """Frames the child delivered as each fault kind (from its records)."""
        counts = {k: 0 for k in CAMERA_FAULT_KINDS}
        path = Path(self.dir) / "camera-faults-done.txt"
        if path.exists():
            for line in path.read_text().splitlines():
                kind = line.split()[0] if line.split() else ""
                if kind in counts:
                    counts[kind] += 1
        return counts
