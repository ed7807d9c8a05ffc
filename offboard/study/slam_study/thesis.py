"""The thesis's published numbers that this project has, quoted verbatim from the study's issue.

Only these are shown beside our measurements, labelled "thesis (published)"; every other thesis
cell is reported as "not quoted" rather than reconstructed.
"""

from __future__ import annotations

kNotQuoted = "not quoted"

# Findings (thesis Chapter 4 summary, as quoted in the issue).
kFindings = (
    (
        "rotation hurts more than translation: "
        "1 deg of rotation per frame ~ 4 mm translational error "
        "and ~20 % rotational error; 10 mm of translation per frame ~ 45 % translational error and "
        "0.2 deg"
    ),
    "z-translation (along the optical axis) and roll cost less than the other axes",
    "the combined effect is multiplicative: 18 mm + 1.8 deg per frame -> 36.10 mm / 1.88 deg",
)

# Table 4.20, the one quoted cell: per-frame motion 18 mm and 1.8 deg (the grid's last cell,
# translation 16-18 mm x rotation 1.6-1.8 deg) -> RPE 36.10 mm / 1.88 deg.
kGridCorner = {
    "trans_bin_mm": (16.0, 18.0),
    "rot_bin_deg": (1.6, 1.8),
    "rpe_trans_mm": 36.10,
    "rpe_rot_deg": 1.88,
}

# Rules of thumb from the findings, used for the side-by-side comparison of the marginal effects:
# pure rotation of 1 deg/frame -> ~4 mm translational RPE and ~20 % rotational error (0.2 deg);
# pure translation of 10 mm/frame -> ~45 % translational error (4.5 mm) and 0.2 deg.
kRotation1DegTransRpeMm = 4.0
kRotation1DegRotRpeFraction = 0.20
kTranslation10MmTransRpeFraction = 0.45
kTranslation10MmRotRpeDeg = 0.2

# Sequence statistics over the full recordings (thesis Table 3.3, quoted in shared/data/README.md).
kTable33 = {
    "freiburg1_xyz": {
        "duration_s": 30.09,
        "frames": 798,
        "trans_m_per_s": 0.244,
        "rot_deg_per_s": 8.92,
    },
    "freiburg1_desk": {
        "duration_s": 23.4,
        "frames": 613,
        "trans_m_per_s": 0.413,
        "rot_deg_per_s": 23.3,
    },
}
