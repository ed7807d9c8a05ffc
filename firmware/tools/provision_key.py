#!/usr/bin/env python3
"""Makes the EEPROM image that provisions a craft's control-link MAC key (flashed over USB with
firmware/flash.sh PORT KEY.hex; never sent over WiFi).

Record at EEPROM address 0 (firmware/core/key_store.h): "RGK1" | key[16] | CRC-16/CCITT-FALSE of
the 20 bytes before it, little-endian.

  provision_key.py --key-hex 000102...0f --out key.hex     # a given key (32 hex digits)
  provision_key.py --new --out key.hex                      # a fresh random key, printed once
Put the same key (hex) in the ground station's config (control_key_hex).
"""

import argparse
import secrets
import sys

MAGIC = b"RGK1"


def crc16_ccitt(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def key_record(key: bytes) -> bytes:
    if len(key) != 16:
        raise ValueError(f"key must be 16 bytes, got {len(key)}")
    if key in (bytes(16), b"\xff" * 16):
        raise ValueError("all-zero / all-0xFF keys are refused by the firmware")
    body = MAGIC + key
    return body + crc16_ccitt(body).to_bytes(2, "little")


def intel_hex(data: bytes, address: int = 0) -> str:
    lines = []
    for off in range(0, len(data), 16):
        chunk = data[off : off + 16]
        addr = address + off
        rec = bytes([len(chunk), addr >> 8, addr & 0xFF, 0]) + chunk
        lines.append(":" + rec.hex().upper() + f"{(-sum(rec)) & 0xFF:02X}")
    lines.append(":00000001FF")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description="write the EEPROM image holding the control MAC key")
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--key-hex", help="the 16-byte key as 32 hex digits")
    g.add_argument("--new", action="store_true", help="generate a fresh random key and print it")
    ap.add_argument(
        "--out", required=True, help="Intel HEX file to write (for avrdude -U eeprom:w:)"
    )
    ap.add_argument("--raw-out", help="also write the raw 22-byte record (e.g. for simavr)")
    args = ap.parse_args()
    try:
        key = secrets.token_bytes(16) if args.new else bytes.fromhex(args.key_hex)
        rec = key_record(key)
    except ValueError as e:
        print(f"provision_key: {e}", file=sys.stderr)
        return 2
    with open(args.out, "w", encoding="ascii") as f:
        f.write(intel_hex(rec))
    if args.raw_out:
        with open(args.raw_out, "wb") as f:
            f.write(rec)
    if args.new:
        print(f"control_key_hex = {key.hex()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
