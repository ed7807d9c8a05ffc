"""slam_study: the spatial-velocity study (thesis Chapter 4) regenerated on real TUM RGB-D data.

Drives the SLAM engine's `slam-eval` over datasets x detector x back-end x frame-rate divisor k,
classifies every consecutive frame pair by its ground-truth motion, bins the per-pair relative pose
error (RPE) the way the thesis's Tables 4.14-4.21 do, and writes a Markdown/CSV/PNG report.

Entry point: `python -m slam_study {run,report,analyze,guide}` (see `--help`).
"""

__all__ = ["guide", "pairs", "report", "se3", "sweep", "tables", "thesis", "tum", "velocity"]
