// Pin and peripheral assignment of the Arduino Uno WiFi (ATmega328P @ 16 MHz) in this design.
// See docs/firmware.md for the wiring to the APM 2.6 and the WiFi bridge.
//   D0/D1  (PD0/PD1, USART0)  WiFi bridge link, 1000000 baud 8N1, one text line per request/reply
//   D2     (PD2, INT0)        MAVLink telemetry RX from the APM's telemetry port TX (software UART)
//   D9     (PB1)              RC channel 1 roll     -> APM RC input 1
//   D10    (PB2)              RC channel 2 pitch    -> APM RC input 2
//   D11    (PB3)              RC channel 3 throttle -> APM RC input 3
//   D12    (PB4)              RC channel 4 yaw      -> APM RC input 4
// Timers: Timer0 = 1 kHz millisecond clock, Timer1 = RC pulse sequencer, Timer2 = software-UART bit
// clock.
#ifndef FIRMWARE_AVR_BOARD_H_
#define FIRMWARE_AVR_BOARD_H_

#include <avr/io.h>
#include <stdint.h>

#include "rgbd_control/control_spec_generated.h"

namespace board {

/// PORTB bit of RC channel 1..4 (index 0..3, ArduPilot order).
constexpr uint8_t kPwmPortBBits[4] = {_BV(PB1), _BV(PB2), _BV(PB3), _BV(PB4)};
constexpr uint8_t kPwmPortBMask = _BV(PB1) | _BV(PB2) | _BV(PB3) | _BV(PB4);

/// Bridge link: 1000000 baud is exact at 16 MHz (U2X0=1, UBRR0 = 16e6 / (8 * 1000000) - 1 = 1; the
/// ESP8266's UART runs it too). At 500000 a command cycle was 16.4 ms in simavr (request
/// and reply bytes half of it); at 250000 a 243-byte reply alone took 10 ms. 2 Mbaud (UBRR0 = 0)
/// would leave the RX ISR 80 cycles per byte, too few beside the soft-UART and PWM interrupts.
constexpr uint32_t kBridgeBaud = rgbd_control::kBridgeBaud;  // control_spec.json serial_link.baud
constexpr uint16_t kBridgeUbrr = 1;
static_assert(16000000UL / (8UL * kBridgeBaud) - 1 == kBridgeUbrr, "UBRR0 must match the baud");
static_assert(16000000UL % (8UL * kBridgeBaud) == 0, "the bridge baud must be exact at 16 MHz");

/// MAVLink telemetry baud: ArduCopter's default SERIAL1_BAUD (57 = 57600) on the APM 2.6 telemetry
/// port.
constexpr uint32_t kMavlinkBaud = 57600;

}  // namespace board

#endif  // FIRMWARE_AVR_BOARD_H_
