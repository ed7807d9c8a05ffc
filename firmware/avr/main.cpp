// ATmega328P firmware entry point: wires the AVR drivers to the core logic. All decisions (parsing,
// authentication, arming, failsafe, limits, PWM schedule) are in firmware/core; this file only
// moves bytes and time between the peripherals and the core.
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/wdt.h>

#include "../core/controller.h"
#include "../core/imu_cache.h"
#include "../core/key_store.h"
#include "../core/line_assembler.h"
#include "../core/mavlink_imu_reader.h"
#include "../core/pwm_schedule.h"
#include "../core/seq_store.h"
#include "drivers.h"

namespace {

/// Sequence floors in the two EEPROM slots (core/seq_store.h). eeprom_update_block blocks the main
/// loop ~3.4 ms per changed byte, once per 65536 commands; the RC pulses are interrupt-driven.
class EepromSeqStore final : public fw::SeqStore {
 public:
  static uint32_t load() {
    uint8_t slots[fw::kSeqSlotsBytes];
    read(slots);
    return fw::load_seq_floor(slots);
  }
  void persist_seq_floor(uint32_t floor) override {
    uint8_t slots[fw::kSeqSlotsBytes];
    read(slots);
    uint8_t slot[fw::kSeqSlotBytes];
    fw::encode_seq_slot(floor, slot);
    const uint16_t addr = static_cast<uint16_t>(fw::kSeqSlotsEepromAddress +
                                                fw::seq_slot_to_write(slots) * fw::kSeqSlotBytes);
    wdt_reset();
    eeprom_update_block(slot, reinterpret_cast<void*>(addr), sizeof(slot));
  }

 private:
  static void read(uint8_t* slots) {
    eeprom_read_block(slots, reinterpret_cast<const void*>(fw::kSeqSlotsEepromAddress),
                      fw::kSeqSlotsBytes);
  }
};

/// The application: owns every piece of state the main loop uses (no globals).
class App {
 public:
  App(const uint8_t* key, uint32_t seq_floor) : controller_(key, seq_floor, &seq_store_) {}

  void init() {
    uint16_t out[fw::kChannelCount];
    uint16_t ticks[fw::kScheduleSlots];
    controller_.outputs_us(out);
    fw::make_pwm_schedule(out, ticks);
    drivers::pwm_init(ticks);
  }

  void loop_once() {
    const uint32_t now_ms = drivers::millis();
    uint8_t b;
    while (drivers::telemetry_read(&b)) mavlink_.feed(b, now_ms, imu_);
    receive(now_ms);
    // A reply is formatted into reply_, which the UART is still sending until it is idle; the
    // request waits in the assembler meanwhile (receive() stops feeding it).
    if (pending_ != fw::LineEvent::kNone && !drivers::bridge_tx_busy()) {
      size_t n = 0;
      if (pending_ == fw::LineEvent::kLine) {
        n = controller_.handle_line(assembler_.line(), assembler_.length(), now_ms, imu_, reply_,
                                    sizeof(reply_));
      } else {
        const fw::Status status =
            pending_ == fw::LineEvent::kTooLong ? fw::Status::kTooLong : fw::Status::kStalled;
        n = controller_.reply_error(status, now_ms, imu_, reply_, sizeof(reply_));
      }
      pending_ = fw::LineEvent::kNone;
      if (n > 0) drivers::bridge_send(reply_, n);
    }
    controller_.update(now_ms);
    uint16_t out[fw::kChannelCount];
    uint16_t ticks[fw::kScheduleSlots];
    controller_.outputs_us(out);
    fw::make_pwm_schedule(out, ticks);
    drivers::pwm_set(ticks);
  }

 private:
  /// Moves bridge bytes from the RX ring into the line assembler - also while a reply is being
  /// sent, so the ring only has to hold what arrives while a request is being checked (limits.h
  /// kBridgeRxRingBytes) - until the next line needs a reply; that line then waits in pending_.
  void receive(uint32_t now_ms) {
    uint8_t b;
    // The rest of an over-long line was answered 414 on its first excess byte; drain it even while
    // that reply is pending, so it cannot fill the RX ring and lose its own newline (which would
    // swallow the next request). Stops right after the newline: the next line waits as usual.
    while (assembler_.discarding() && drivers::bridge_read(&b)) assembler_.feed(b, now_ms);
    while (pending_ == fw::LineEvent::kNone && drivers::bridge_read(&b)) {
      const fw::LineEvent e = assembler_.feed(b, now_ms);
      // kDropped: the line lost bytes in the full RX ring; nothing in it can be trusted, and the
      // sender learns of the loss from the missing reply, as from a request lost on WiFi.
      if (e != fw::LineEvent::kDropped) pending_ = e;
    }
    if (pending_ == fw::LineEvent::kNone) pending_ = assembler_.poll(now_ms);
  }

  EepromSeqStore seq_store_;  // declared before controller_, which holds a pointer to it
  fw::Controller controller_;
  fw::LineAssembler assembler_;
  fw::ImuCache imu_;
  fw::MavlinkImuReader mavlink_;
  char reply_[fw::kReplyBufferBytes];
  /// The assembler's event waiting for a reply (kLine, kTooLong, kStalled), or kNone.
  fw::LineEvent pending_ = fw::LineEvent::kNone;
};

}  // namespace

int main() {
  // A hung main loop must not freeze the last outputs: the watchdog resets the chip, the pulses
  // stop during the reset and the APM's own radio failsafe takes over. 120 ms > the longest loop
  // pass (one SipHash of a 93-byte request, a few ms).
  wdt_enable(WDTO_120MS);
  uint8_t record[fw::kKeyRecordBytes];
  eeprom_read_block(record, reinterpret_cast<const void*>(fw::kKeyRecordEepromAddress),
                    sizeof(record));
  uint8_t key[fw::kKeyBytes];
  const bool has_key = fw::load_key_record(record, key);
  static App app(has_key ? key : nullptr, EepromSeqStore::load());
  for (uint8_t i = 0; i < sizeof(key); ++i) key[i] = 0;
  for (uint8_t i = 0; i < sizeof(record); ++i) record[i] = 0;
  drivers::clock_init();
  app.init();
  drivers::bridge_init();
  drivers::telemetry_init();
  sei();
  for (;;) {
    wdt_reset();
    app.loop_once();
  }
}
