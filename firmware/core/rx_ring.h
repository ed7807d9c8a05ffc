// Receive rings between an interrupt handler (the only producer) and the main loop (the only
// consumer): single-producer single-consumer, lock-free, fixed size, no heap. ByteRing drops a byte
// that finds the ring full. LineRing, for the line-oriented bridge link, never lets a line lose
// bytes in its middle: when a byte finds the ring full, the rest of that line is dropped up to its
// '\n', and the '\n' is replaced by kLineCutMarker, which the line assembler answers by discarding
// the damaged line whole (LineEvent::kDropped). So a request that does not fit is dropped, never
// spliced with its neighbour into a different line.
//
// Thread safety: push*() from one context (an ISR), pop() from one other context (main). The
// indices are single bytes (atomic on the AVR) and every shared field is volatile, so the
// producer's data store is ordered before its head store. dropped_bytes()/cut_lines() are 16-bit:
// read them with interrupts off on the AVR.
#ifndef FIRMWARE_CORE_RX_RING_H_
#define FIRMWARE_CORE_RX_RING_H_

#include <stdint.h>

namespace fw {

/// Put in the line stream where a line lost bytes. NUL is never part of a request line (requests
/// are printable ASCII), and a NUL that arrives on the wire (a break, line noise) means the same:
/// the line around it is not trustworthy.
constexpr uint8_t kLineCutMarker = 0x00;

/// Byte ring of N slots holding up to N - 1 bytes (one slot stays empty to tell full from empty).
template <uint8_t N>
class ByteRing {
  static_assert(N >= 2, "a ring needs at least two slots");

 public:
  /// Producer: appends b; if the ring is full, drops b, counts it and returns false.
  bool push(uint8_t b) {
    if (!try_push(b)) {
      dropped_bytes_ = static_cast<uint16_t>(dropped_bytes_ + 1);
      return false;
    }
    return true;
  }
  /// Consumer: takes the oldest byte into *b; false when the ring is empty.
  bool pop(uint8_t* b) {
    const uint8_t t = tail_;
    if (t == head_) return false;
    *b = data_[t];
    tail_ = next(t);
    return true;
  }
  /// Bytes dropped because the ring was full (diagnostics).
  uint16_t dropped_bytes() const { return dropped_bytes_; }
  /// Bytes the ring holds at most.
  static constexpr uint8_t capacity_bytes() { return static_cast<uint8_t>(N - 1); }

 protected:
  static uint8_t next(uint8_t i) { return static_cast<uint8_t>(i + 1 == N ? 0 : i + 1); }
  bool try_push(uint8_t b) {
    const uint8_t h = head_;
    const uint8_t n = next(h);
    if (n == tail_) return false;
    data_[h] = b;
    head_ = n;
    return true;
  }

  volatile uint8_t data_[N];
  volatile uint8_t head_ = 0;  ///< next slot to write; written by the producer only
  volatile uint8_t tail_ = 0;  ///< next slot to read; written by the consumer only
  volatile uint16_t dropped_bytes_ = 0;
};

/// ByteRing for a '\n'-terminated line stream that drops whole lines, never parts of them.
template <uint8_t N>
class LineRing : public ByteRing<N> {
 public:
  /// Producer: appends b. When b finds the ring full, b and the rest of its line up to its '\n'
  /// are dropped, and kLineCutMarker goes where that '\n' would have gone - or, if the ring is
  /// still full then, before the first byte of a later line that finds room (a line that finds no
  /// room for the marker and its first byte is dropped too; one marker covers both). Bytes of the
  /// cut line already in the ring stay; the consumer discards them when it reaches the marker.
  void push_line_byte(uint8_t b) {
    if (cutting_) {
      drop();
      if (b != '\n') return;
      cutting_ = false;
      marker_owed_ = !this->try_push(kLineCutMarker);
      return;
    }
    if (marker_owed_) {
      if (!this->try_push(kLineCutMarker)) {
        drop();
        cutting_ = b != '\n';
        return;
      }
      marker_owed_ = false;
    }
    if (!this->try_push(b)) {
      drop();
      if (b == '\n') {
        marker_owed_ = true;  // the line is whole but has no room for its end: it goes too
      } else {
        cutting_ = true;
      }
    }
  }

 private:
  void drop() { this->dropped_bytes_ = static_cast<uint16_t>(this->dropped_bytes_ + 1); }

  // Producer only (the ISR): no volatile needed.
  bool cutting_ = false;  ///< dropping the rest of a line that lost a byte; marker owed after it
  bool marker_owed_ = false;  ///< a cut line has ended; kLineCutMarker still to be put in the ring
};

}  // namespace fw

#endif  // FIRMWARE_CORE_RX_RING_H_
