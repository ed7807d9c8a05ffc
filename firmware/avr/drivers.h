// AVR peripheral drivers: registers and interrupt handlers only, no logic. Each driver's state
// shared with its ISR lives in a file-scope struct in drivers.cpp (an ISR has no other way to reach
// it); everything else is passed in from main().
#ifndef FIRMWARE_AVR_DRIVERS_H_
#define FIRMWARE_AVR_DRIVERS_H_

#include <stddef.h>
#include <stdint.h>

namespace drivers {

/// Timer0 as a 1 kHz clock. millis() reads the counter atomically.
void clock_init();
uint32_t millis();

/// Timer1 RC pulse sequencer on PB1..PB4. pwm_set() hands over a new schedule (5 slot lengths in
/// timer ticks, see core/pwm_schedule.h); it takes effect at the start of the next 20 ms frame.
void pwm_init(const uint16_t slot_ticks[5]);
void pwm_set(const uint16_t slot_ticks[5]);

/// USART0 to the WiFi bridge: RX into a line ring (core/rx_ring.h: a line that does not fit is
/// replaced by fw::kLineCutMarker, never cut short), TX of one reply at a time from the caller's
/// buffer (which must stay unchanged until bridge_tx_busy() is false).
void bridge_init();
bool bridge_read(uint8_t* byte);
void bridge_send(const char* data, size_t len);
bool bridge_tx_busy();
/// Bytes dropped because the RX ring was full (diagnostics).
uint16_t bridge_rx_overruns();

/// Software UART receiver (INT0 start edge + Timer2 bit sampling) for MAVLink telemetry on PD2.
void telemetry_init();
bool telemetry_read(uint8_t* byte);
/// Bytes dropped because the telemetry ring was full (diagnostics).
uint16_t telemetry_overruns();

}  // namespace drivers

#endif  // FIRMWARE_AVR_DRIVERS_H_
