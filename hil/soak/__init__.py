"""`make soak`: HIL missions back to back under a seeded schedule of faults (docs/hil.md, Soak)."""
