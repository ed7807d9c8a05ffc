"""Shared pieces of the HIL scenarios: paths and binaries, processes stopped by PID, a ground-truth
pilot (the stand-in ground station for rig self-checks), flight recording, metrics and reports."""
