// EEPROM slots of the sequence-number floor; see seq_store.h.
#include "seq_store.h"

namespace fw {
namespace {

uint32_t load_le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

bool slot_valid(const uint8_t* slot, uint32_t* value) {
  const uint32_t v = load_le32(slot);
  if (load_le32(slot + 4) != static_cast<uint32_t>(~v)) return false;
  *value = v;
  return true;
}

}  // namespace

uint32_t load_seq_floor(const uint8_t slots[kSeqSlotsBytes]) {
  uint32_t best = 0;
  for (size_t i = 0; i < 2; ++i) {
    uint32_t v = 0;
    if (slot_valid(slots + i * kSeqSlotBytes, &v) && v > best) best = v;
  }
  return best;
}

uint8_t seq_slot_to_write(const uint8_t slots[kSeqSlotsBytes]) {
  uint32_t v0 = 0;
  uint32_t v1 = 0;
  const bool ok0 = slot_valid(slots, &v0);
  const bool ok1 = slot_valid(slots + kSeqSlotBytes, &v1);
  if (!ok0) return 0;
  if (!ok1) return 1;
  return v0 <= v1 ? 0 : 1;
}

void encode_seq_slot(uint32_t floor, uint8_t out[kSeqSlotBytes]) {
  const uint32_t inv = ~floor;
  for (size_t i = 0; i < 4; ++i) {
    out[i] = static_cast<uint8_t>(floor >> (8 * i));
    out[4 + i] = static_cast<uint8_t>(inv >> (8 * i));
  }
}

}  // namespace fw
