// AVR peripheral drivers (registers + ISRs only); see drivers.h and board.h.
// ISR timing budget: the RC pulse edges come from the Timer1 compare ISR, so every other ISR is
// kept to a few microseconds (the longest delays an edge by its own length, < 4 us).
#include "drivers.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../core/limits.h"
#include "../core/rx_ring.h"
#include "board.h"

namespace drivers {
namespace {

// ---- shared with ISRs
// ----------------------------------------------------------------------------
struct ClockState {
  volatile uint32_t ms;
};
ClockState g_clock = {0};

struct PwmState {
  uint16_t active_ticks[5];      // schedule of the frame being played (ISR only)
  uint16_t pending_ticks[2][5];  // double buffer: main fills [1 - ready], then flips `ready`
  volatile uint8_t ready;        // buffer the ISR copies at the next frame start (1-byte: atomic)
  uint8_t slot;                  // slot being played (ISR only)
};
PwmState g_pwm;

/// Telemetry RX ring: 64 bytes = 11 ms of 57600-baud MAVLink, far more than one main-loop pass.
constexpr uint8_t kTelemetryRingBytes = 64;

/// Bridge RX: fw::kBridgeRxRingBytes (core/limits.h, sized for two queued requests); a request
/// that does not fit is dropped whole (core/rx_ring.h).
fw::LineRing<fw::kBridgeRxRingBytes> g_bridge_rx;
struct TxState {
  const char* volatile ptr;
  volatile uint16_t left;
};
TxState g_tx = {nullptr, 0};

fw::ByteRing<kTelemetryRingBytes> g_telemetry_rx;
struct SoftUartState {
  uint16_t sample_pos_fp;  // next sample time, Timer2 ticks in 8.8 fixed point (mod 256 ticks)
  uint8_t bit_index;       // 0 = start bit, 1..8 data bits 0..7
  uint8_t shift;
};
SoftUartState g_suart;

/// One MAVLink bit in Timer2 ticks (16 MHz / 8 = 2 ticks/us), 8.8 fixed point: 34.72 ticks at
/// 57600.
constexpr uint16_t kBitTicksFp =
    static_cast<uint16_t>((F_CPU / 8UL * 256UL + board::kMavlinkBaud / 2) / board::kMavlinkBaud);

}  // namespace

// ---- clock
// -----------------------------------------------------------------------------------------
void clock_init() {
  OCR0A = 249;          // 16 MHz / 64 / 250 = 1 kHz
  TCCR0A = _BV(WGM01);  // CTC
  TCCR0B = _BV(CS01) | _BV(CS00);
  TIMSK0 = _BV(OCIE0A);
}

uint32_t millis() {
  uint32_t v;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { v = g_clock.ms; }
  return v;
}

// Not timing critical: let the RC pulse ISR interrupt it.
ISR(TIMER0_COMPA_vect, ISR_NOBLOCK) { g_clock.ms = g_clock.ms + 1; }

// ---- RC pulses
// ---------------------------------------------------------------------------------------
void pwm_init(const uint16_t slot_ticks[5]) {
  for (uint8_t i = 0; i < 5; ++i) {
    g_pwm.active_ticks[i] = slot_ticks[i];
    g_pwm.pending_ticks[0][i] = slot_ticks[i];
  }
  g_pwm.ready = 0;
  g_pwm.slot = 4;  // start in the gap; the first compare match starts channel 1
  PORTB &= static_cast<uint8_t>(~board::kPwmPortBMask);
  DDRB |= board::kPwmPortBMask;
  // simavr 1.6 keeps the old TOP unless OCR1A is written before TCCR1A/TCCR1B.
  OCR1A = 1000;
  TCNT1 = 0;
  TCCR1A = 0;
  TCCR1B = _BV(WGM12) | _BV(CS11);  // CTC, TOP = OCR1A, prescaler 8: 0.5 us per tick
  TIMSK1 = _BV(OCIE1A);
}

// Lock-free (no cli): a disabled-interrupt window here would delay RC pulse edges. The ISR only
// reads buffer `ready`; main writes the other one and then flips the index with one byte store.
void pwm_set(const uint16_t slot_ticks[5]) {
  const uint8_t fill = static_cast<uint8_t>(1 - g_pwm.ready);
  for (uint8_t i = 0; i < 5; ++i) g_pwm.pending_ticks[fill][i] = slot_ticks[i];
  g_pwm.ready = fill;
}

// Every edge is written first thing in the ISR, so all edges share one fixed latency and pulse
// widths equal the programmed slot lengths (CTC restarts the count in hardware at each match).
// After the edge, interrupts are re-enabled: the rest of this ISR must not delay the software
// UART's bit sampling (the next compare match is >= 900 us away, so it cannot re-enter).
ISR(TIMER1_COMPA_vect) {
  uint8_t next = static_cast<uint8_t>(g_pwm.slot + 1);
  if (next == 5) next = 0;
  uint8_t port = static_cast<uint8_t>(PORTB & ~board::kPwmPortBMask);
  if (next < 4) port = static_cast<uint8_t>(port | board::kPwmPortBBits[next]);
  PORTB = port;
  sei();
  if (next == 0) {
    const uint8_t r = g_pwm.ready;
    for (uint8_t i = 0; i < 5; ++i) g_pwm.active_ticks[i] = g_pwm.pending_ticks[r][i];
  }
  OCR1A = static_cast<uint16_t>(g_pwm.active_ticks[next] - 1);
  g_pwm.slot = next;
}

// ---- bridge UART
// -------------------------------------------------------------------------------------
void bridge_init() {
  UBRR0 = board::kBridgeUbrr;
  UCSR0A = _BV(U2X0);
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

bool bridge_read(uint8_t* byte) { return g_bridge_rx.pop(byte); }

void bridge_send(const char* data, size_t len) {
  if (len == 0) return;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    g_tx.ptr = data;
    g_tx.left = static_cast<uint16_t>(len);
    UCSR0B |= _BV(UDRIE0);
  }
}

bool bridge_tx_busy() {
  uint16_t left;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { left = g_tx.left; }
  return left != 0;
}

uint16_t bridge_rx_overruns() {
  uint16_t v;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { v = g_bridge_rx.dropped_bytes(); }
  return v;
}

// Reading UDR0 clears the interrupt source, so interrupts can be re-enabled at once: RC pulse edges
// then wait only for this ISR's prologue, not its body.
ISR(USART_RX_vect) {
  const uint8_t b = UDR0;
  sei();
  g_bridge_rx.push_line_byte(b);
}

// The data-register-empty interrupt is masked while this ISR runs (it would re-trigger as soon as
// UDR0 moves to the shift register), so interrupts can be re-enabled after the byte is written.
ISR(USART_UDRE_vect) {
  UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));
  const char* p = g_tx.ptr;
  UDR0 = static_cast<uint8_t>(*p);
  sei();
  g_tx.ptr = p + 1;
  const uint16_t left = static_cast<uint16_t>(g_tx.left - 1);
  g_tx.left = left;
  cli();
  if (left != 0) UCSR0B |= _BV(UDRIE0);
}

// ---- telemetry software UART
// -------------------------------------------------------------------------
void telemetry_init() {
  DDRD &= static_cast<uint8_t>(~_BV(PD2));
  PORTD |= _BV(PD2);   // pull-up: idle line high
  TCCR2A = 0;          // normal mode, free running
  TCCR2B = _BV(CS21);  // prescaler 8: 0.5 us per tick
  EICRA = _BV(ISC01);  // INT0 on the falling (start-bit) edge
  EIFR = _BV(INTF0);
  EIMSK = _BV(INT0);
}

bool telemetry_read(uint8_t* byte) { return g_telemetry_rx.pop(byte); }

uint16_t telemetry_overruns() {
  uint16_t v;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { v = g_telemetry_rx.dropped_bytes(); }
  return v;
}

// Start edge: schedule the first sample in the middle of the start bit. The compare ISR's entry
// latency equals this ISR's, so it cancels out of the sample position.
ISR(INT0_vect) {
  const uint8_t edge = TCNT2;
  EIMSK = 0;
  const uint16_t pos = static_cast<uint16_t>((static_cast<uint16_t>(edge) << 8) + kBitTicksFp / 2);
  g_suart.sample_pos_fp = pos;
  g_suart.bit_index = 0;
  OCR2A = static_cast<uint8_t>(pos >> 8);
  TIFR2 = _BV(OCF2A);
  TIMSK2 = _BV(OCIE2A);
}

// Samples start bit (must be low), then data bits 0..7. The byte is finished in the middle of bit
// 7: from there until the next start bit the line can only rise (bit 7 -> stop bit) or stay high,
// so INT0 is re-armed 1.5 bit times before the next possible start edge instead of 0.5 (after a
// stop-bit sample), which keeps back-to-back bytes aligned even when this ISR is delayed by the RC
// pulse ISR. Stop bits are not checked; MAVLink's CRC rejects any corrupted frame.
ISR(TIMER2_COMPA_vect) {
  const bool high = (PIND & _BV(PD2)) != 0;
  const uint8_t i = g_suart.bit_index;
  if (i == 0) {
    if (high) {  // a glitch, not a start bit
      TIMSK2 = 0;
      EIFR = _BV(INTF0);
      EIMSK = _BV(INT0);
      return;
    }
  } else {
    g_suart.shift = static_cast<uint8_t>((g_suart.shift >> 1) | (high ? 0x80 : 0));
    if (i == 8) {
      g_telemetry_rx.push(g_suart.shift);
      TIMSK2 = 0;
      EIFR = _BV(INTF0);
      EIMSK = _BV(INT0);
      return;
    }
  }
  g_suart.bit_index = static_cast<uint8_t>(i + 1);
  const uint16_t pos = static_cast<uint16_t>(g_suart.sample_pos_fp + kBitTicksFp);
  g_suart.sample_pos_fp = pos;
  OCR2A = static_cast<uint8_t>(pos >> 8);
}

}  // namespace drivers
