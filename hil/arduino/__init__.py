"""hil/arduino: run the real ATmega328P firmware image under simavr (fw_sim harness)."""
