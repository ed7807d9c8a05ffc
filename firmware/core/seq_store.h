// Replay protection across resets: the firmware never accepts a sequence number at or below a
// floor kept in EEPROM. Before it accepts a number above the current reservation it persists a new
// reservation (that number + kSeqReserveCount) first, so one EEPROM write covers the next 65536
// commands (~22 min at 50 Hz; the ATmega's 100000-cycle EEPROM endurance lasts ~4 years of
// continuous commanding). After a reset the last accepted number is the stored reservation: a
// recorded command can never be replayed, and the ground station resumes after the `seq` of the
// first reply (its 409 reply carries it).
//
// EEPROM layout: two 8-byte slots at kSeqSlotsEepromAddress, each u32 floor + u32 ~floor
// (little-endian). Writes alternate to the slot with the lower (or invalid) value, so a write torn
// by a power loss leaves the other slot, whose reservation still covers every accepted number.
#ifndef FIRMWARE_CORE_SEQ_STORE_H_
#define FIRMWARE_CORE_SEQ_STORE_H_

#include <stddef.h>
#include <stdint.h>

namespace fw {

/// Sequence numbers reserved per EEPROM write (see the file comment for the endurance figure).
constexpr uint32_t kSeqReserveCount = 65536;
constexpr uint16_t kSeqSlotsEepromAddress = 32;  ///< after the 22-byte key record
constexpr size_t kSeqSlotBytes = 8;
constexpr size_t kSeqSlotsBytes = 2 * kSeqSlotBytes;

/// Persists a new sequence floor (implemented over EEPROM by the AVR main, by fakes in tests).
/// Called from the main loop only; must complete before returning.
class SeqStore {
 public:
  virtual void persist_seq_floor(uint32_t floor) = 0;

 protected:
  ~SeqStore() = default;  // not deleted through this interface (no heap on the ATmega)
};

/// Highest valid floor in the two slots; 0 when neither is valid (erased EEPROM).
uint32_t load_seq_floor(const uint8_t slots[kSeqSlotsBytes]);
/// Index (0/1) of the slot the next floor goes to: the invalid one, else the lower one.
uint8_t seq_slot_to_write(const uint8_t slots[kSeqSlotsBytes]);
/// Encodes one slot.
void encode_seq_slot(uint32_t floor, uint8_t out[kSeqSlotBytes]);

}  // namespace fw

#endif  // FIRMWARE_CORE_SEQ_STORE_H_
