// Placeholder replaced by the golden-vector replay.
