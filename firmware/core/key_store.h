// The per-craft MAC key as stored in EEPROM (written at flash time by
// firmware/tools/provision_key.py through avrdude, or over the USB serial port; there is no code
// path that writes it from the WiFi link). Record layout at EEPROM address 0, 22 bytes:
//   "RGK1" | key[16] | CRC-16/CCITT-FALSE of the previous 20 bytes, little-endian.
// An erased (all 0xFF), all-zero or corrupt record yields no key: every command is then refused
// (503).
#ifndef FIRMWARE_CORE_KEY_STORE_H_
#define FIRMWARE_CORE_KEY_STORE_H_

#include <stddef.h>
#include <stdint.h>

namespace fw {

constexpr size_t kKeyBytes = 16;
constexpr size_t kKeyRecordBytes = 22;
constexpr uint16_t kKeyRecordEepromAddress = 0;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): check value 0x29B1 for "123456789".
uint16_t crc16_ccitt(const uint8_t* data, size_t len);

/// Validates a record and copies its key to key_out; false (key_out untouched) when invalid.
bool load_key_record(const uint8_t record[kKeyRecordBytes], uint8_t key_out[kKeyBytes]);

/// Builds a record for `key` (used by tests and the native provisioning check).
void make_key_record(const uint8_t key[kKeyBytes], uint8_t record_out[kKeyRecordBytes]);

}  // namespace fw

#endif  // FIRMWARE_CORE_KEY_STORE_H_
