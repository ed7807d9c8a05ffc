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

inline uint64_t rotl(uint64_t x, unsigned b) { return (x << b) | (x >> (64U - b)); }

inline uint64_t load_le64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

inline void round(uint64_t& v0, uint64_t& v1, uint64_t& v2, uint64_t& v3) {
  v0 += v1;
  v1 = rotl(v1, 13);
  v1 ^= v0;
  v0 = rotl(v0, 32);
  v2 += v3;
  v3 = rotl(v3, 16);
  v3 ^= v2;
  v0 += v3;
  v3 = rotl(v3, 21);
  v3 ^= v0;
  v2 += v1;
  v1 = rotl(v1, 17);
  v1 ^= v2;
  v2 = rotl(v2, 32);
}

}  // namespace siphash_detail

/// Computes SipHash-2-4 of `len` bytes at `msg` (may be null when len == 0) under the 16-byte `key`
/// and returns the tag as a 64-bit word (serialise with siphash24_tag_bytes()).
inline uint64_t siphash24(const uint8_t key[kSipHashKeyBytes], const uint8_t* msg, size_t len) {
  using namespace siphash_detail;
  const uint64_t k0 = load_le64(key);
  const uint64_t k1 = load_le64(key + 8);
  uint64_t v0 = 0x736f6d6570736575ULL ^ k0;
  uint64_t v1 = 0x646f72616e646f6dULL ^ k1;
  uint64_t v2 = 0x6c7967656e657261ULL ^ k0;
  uint64_t v3 = 0x7465646279746573ULL ^ k1;
  const size_t full_blocks = len / 8;
  for (size_t i = 0; i < full_blocks; ++i) {
    const uint64_t m = load_le64(msg + 8 * i);
    v3 ^= m;
    round(v0, v1, v2, v3);
    round(v0, v1, v2, v3);
    v0 ^= m;
  }
  uint64_t b = static_cast<uint64_t>(len & 0xFFU) << 56;
  const size_t tail = len & 7U;
  for (size_t i = 0; i < tail; ++i) {
    b |= static_cast<uint64_t>(msg[8 * full_blocks + i]) << (8 * i);
  }
  v3 ^= b;
  round(v0, v1, v2, v3);
  round(v0, v1, v2, v3);
  v0 ^= b;
  v2 ^= 0xFF;
  for (int i = 0; i < 4; ++i) round(v0, v1, v2, v3);
  return v0 ^ v1 ^ v2 ^ v3;
}

/// Writes the 8 tag bytes in wire order (little-endian of the tag word) to `out`.
inline void siphash24_tag_bytes(uint64_t tag, uint8_t out[kSipHashTagBytes]) {
  for (size_t i = 0; i < kSipHashTagBytes; ++i) {
    out[i] = static_cast<uint8_t>(tag >> (8 * i));
  }
}

}  // namespace rgbd_control

#endif  // RGBD_CONTROL_SIPHASH24_H_
