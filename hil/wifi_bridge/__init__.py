"""WiFi-bridge emulator: the HTTP side of the Arduino Uno WiFi's bridge chip, on loopback."""

from wifi_bridge.bridge import BridgeOptions, WifiBridgeEmulator

__all__ = ["BridgeOptions", "WifiBridgeEmulator"]
