"""quad-control's MCAP flight recordings (docs/recording.md): tolerant reading, summaries, SLAM
replay."""
