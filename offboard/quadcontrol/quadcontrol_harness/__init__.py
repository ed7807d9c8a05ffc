"""A running quad-control for tools and tests: the process started from a configuration that feeds
it the TUM replay and points it at a firmware double behind the control link's WiFi-bridge emulator
(firmware_double.py). Used by the dashboard tests, offboard/quadcontrol/tools/measure_links.py and
hil/recording_bench.py. Everything listens on 127.0.0.1 only; quad-control is stopped by its PID.
"""
