// SipHash-2-4 (Aumasson & Bernstein, 2012): the message authentication code of the control link.
//
// One implementation shared by the ATmega328P firmware (avr-gcc 5.4, gnu++14, no STL) and the
// ground-station codec (C++17), so it uses only <stdint.h> and <stddef.h>. A 128-bit key, a 64-bit
// tag; the tag is serialised as its 8 bytes in the reference implementation's order (little-endian
// of the final 64-bit word), which is how the paper's test vectors are printed.
// Pure functions, no state: thread-safe and re-entrant.
#ifndef RGBD_CONTROL_SIPHASH24_H_
#define RGBD_CONTROL_SIPHASH24_H_

#include <stddef.h>
#include <stdint.h>

namespace rgbd_control {

/// Key length (bytes) and tag length (bytes) of SipHash-2-4.
constexpr size_t kSipHashKeyBytes = 16;
constexpr size_t kSipHashTagBytes = 8;

namespace siphash_detail {

// The 64-bit state words are kept as two 32-bit halves: on the 8-bit AVR, avr-gcc turns every
// 64-bit shift into a bit-by-bit library loop (a SipRound cost ~2900 cycles), while 32-bit shifts by
// constants compile to short inline sequences and a rotation by 32 is a free swap of the halves.
struct Word {
  uint32_t lo;
  uint32_t hi;
};

inline Word add(Word a, Word b) {
  Word r;
  r.lo = a.lo + b.lo;
  r.hi = a.hi + b.hi + (r.lo < a.lo ? 1U : 0U);
  return r;
}

inline Word xor_(Word a, Word b) {
  Word r;
  r.lo = a.lo ^ b.lo;
  r.hi = a.hi ^ b.hi;
  return r;
}

/// Rotation left by N, 0 < N < 32.
template <unsigned N>
inline Word rotl(Word x) {
  static_assert(N > 0 && N < 32, "use swap32 for 32");
  Word r;
  r.hi = (x.hi << N) | (x.lo >> (32U - N));
  r.lo = (x.lo << N) | (x.hi >> (32U - N));
  return r;
}

inline Word swap32(Word x) {
  Word r;
  r.lo = x.hi;
  r.hi = x.lo;
  return r;
}

inline uint32_t load_le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) |
         (static_cast<uint32_t>(p[2]) << 16) | (static_cast<uint32_t>(p[3]) << 24);
}

inline Word load_le64(const uint8_t* p) {
  Word w;
  w.lo = load_le32(p);
  w.hi = load_le32(p + 4);
  return w;
}

inline Word word(uint64_t v) {
  Word w;
  w.lo = static_cast<uint32_t>(v);
  w.hi = static_cast<uint32_t>(v >> 32);
  return w;
}

inline void round(Word& v0, Word& v1, Word& v2, Word& v3) {
  v0 = add(v0, v1); v1 = rotl<13>(v1); v1 = xor_(v1, v0); v0 = swap32(v0);
  v2 = add(v2, v3); v3 = rotl<16>(v3); v3 = xor_(v3, v2);
  v0 = add(v0, v3); v3 = rotl<21>(v3); v3 = xor_(v3, v0);
  v2 = add(v2, v1); v1 = rotl<17>(v1); v1 = xor_(v1, v2); v2 = swap32(v2);
}

}  // namespace siphash_detail

/// Computes SipHash-2-4 of `len` bytes at `msg` (may be null when len == 0) under the 16-byte `key`
/// and returns the tag as a 64-bit word (serialise with siphash24_tag_bytes()).
inline uint64_t siphash24(const uint8_t key[kSipHashKeyBytes], const uint8_t* msg, size_t len) {
  using namespace siphash_detail;
  const Word k0 = load_le64(key);
  const Word k1 = load_le64(key + 8);
  Word v0 = xor_(word(0x736f6d6570736575ULL), k0);
  Word v1 = xor_(word(0x646f72616e646f6dULL), k1);
  Word v2 = xor_(word(0x6c7967656e657261ULL), k0);
  Word v3 = xor_(word(0x7465646279746573ULL), k1);
  const size_t full_blocks = len / 8;
  for (size_t i = 0; i < full_blocks; ++i) {
    const Word m = load_le64(msg + 8 * i);
    v3 = xor_(v3, m);
    round(v0, v1, v2, v3);
    round(v0, v1, v2, v3);
    v0 = xor_(v0, m);
  }
  uint8_t last[8] = {0, 0, 0, 0, 0, 0, 0, static_cast<uint8_t>(len & 0xFFU)};
  const size_t tail = len & 7U;
  for (size_t i = 0; i < tail; ++i) last[i] = msg[8 * full_blocks + i];
  const Word b = load_le64(last);
  v3 = xor_(v3, b);
  round(v0, v1, v2, v3);
  round(v0, v1, v2, v3);
  v0 = xor_(v0, b);
  v2.lo ^= 0xFFU;
  for (int i = 0; i < 4; ++i) round(v0, v1, v2, v3);
  const Word r = xor_(xor_(v0, v1), xor_(v2, v3));
  return (static_cast<uint64_t>(r.hi) << 32) | r.lo;
}

/// Writes the 8 tag bytes in wire order (little-endian of the tag word) to `out`.
inline void siphash24_tag_bytes(uint64_t tag, uint8_t out[kSipHashTagBytes]) {
  for (size_t i = 0; i < kSipHashTagBytes; ++i) {
    out[i] = static_cast<uint8_t>(tag >> (8 * i));
  }
}

}  // namespace rgbd_control

#endif  // RGBD_CONTROL_SIPHASH24_H_
