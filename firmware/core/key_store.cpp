// EEPROM key record validation; see key_store.h.
#include "key_store.h"

namespace fw {
namespace {
const uint8_t kMagic[4] = {'R', 'G', 'K', '1'};
}  // namespace

uint16_t crc16_ccitt(const uint8_t* data, size_t len) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < len; ++i) {
    crc = static_cast<uint16_t>(crc ^ (static_cast<uint16_t>(data[i]) << 8));
    for (int b = 0; b < 8; ++b) {
      crc = (crc & 0x8000U) ? static_cast<uint16_t>((crc << 1) ^ 0x1021U)
                            : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

bool load_key_record(const uint8_t record[kKeyRecordBytes], uint8_t key_out[kKeyBytes]) {
  for (size_t i = 0; i < 4; ++i) {
    if (record[i] != kMagic[i]) return false;
  }
  const uint16_t crc = crc16_ccitt(record, 20);
  if (record[20] != static_cast<uint8_t>(crc & 0xFF) ||
      record[21] != static_cast<uint8_t>(crc >> 8)) {
    return false;
  }
  bool all_zero = true;
  bool all_ff = true;
  for (size_t i = 0; i < kKeyBytes; ++i) {
    all_zero = all_zero && record[4 + i] == 0x00;
    all_ff = all_ff && record[4 + i] == 0xFF;
  }
  if (all_zero || all_ff) return false;
  for (size_t i = 0; i < kKeyBytes; ++i) key_out[i] = record[4 + i];
  return true;
}

void make_key_record(const uint8_t key[kKeyBytes], uint8_t record_out[kKeyRecordBytes]) {
  for (size_t i = 0; i < 4; ++i) record_out[i] = kMagic[i];
  for (size_t i = 0; i < kKeyBytes; ++i) record_out[4 + i] = key[i];
  const uint16_t crc = crc16_ccitt(record_out, 20);
  record_out[20] = static_cast<uint8_t>(crc & 0xFF);
  record_out[21] = static_cast<uint8_t>(crc >> 8);
}

}  // namespace fw
