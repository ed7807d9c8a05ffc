// Unit tests of the bridge receive path's core: the line ring (core/rx_ring.h) feeding the line
// assembler. The ring must hold two longest valid requests queued behind the one being answered,
// and a request that does not fit must be dropped whole - never spliced with a neighbour into a
// different line. GIVEN/WHEN/THEN in each test or table row; deterministic (seeded generator).
#include <gtest/gtest.h>
#include <stdint.h>

#include <string>
#include <vector>

#include "limits.h"
#include "line_assembler.h"
#include "rx_ring.h"

namespace {

/// A valid-looking request of exactly kLongestValidRequestBytes, distinguishable by `id`.
std::string longest_request(uint32_t id) {
  std::string s = "PUT /control?seq=" + std::to_string(4000000000u + id) +
                  "&arm=1&roll=2000&pitch=2000&thr=2000&yaw=2000&mac=";
  s.append(fw::kLongestValidRequestBytes - s.size(), static_cast<char>('a' + id % 6));
  return s;
}

template <uint8_t N>
void push_all(fw::LineRing<N>* ring, const std::string& bytes) {
  for (char c : bytes) ring->push_line_byte(static_cast<uint8_t>(c));
}

/// What the main loop gets out of the assembler: kLine contents, and "<dropped>" per kDropped.
template <uint8_t N>
std::vector<std::string> drain(fw::LineRing<N>* ring, fw::LineAssembler* a) {
  std::vector<std::string> out;
  uint8_t b;
  while (ring->pop(&b)) {
    const fw::LineEvent e = a->feed(b, 0);
    if (e == fw::LineEvent::kLine) out.emplace_back(a->line(), a->length());
    if (e == fw::LineEvent::kDropped) out.emplace_back("<dropped>");
    if (e == fw::LineEvent::kTooLong) out.emplace_back("<too long>");
  }
  return out;
}

TEST(RxRing, LongestValidRequestMatchesItsDefinition) {
  EXPECT_EQ(longest_request(0).size(), size_t{fw::kLongestValidRequestBytes});
  EXPECT_LE(fw::kLongestValidRequestBytes, fw::kMaxRequestBytes);
}

TEST(RxRing, BridgeRingHoldsTwoQueuedLongestRequestsWithCrLf) {
  // GIVEN the bridge ring, WHEN two longest valid requests with "\r\n" arrive while the main loop
  // reads nothing (it is checking the request before them)
  fw::LineRing<fw::kBridgeRxRingBytes> ring;
  fw::LineAssembler a;
  const std::string r1 = longest_request(1), r2 = longest_request(2);
  push_all(&ring, r1 + "\r\n" + r2 + "\r\n");
  // THEN both are kept whole, nothing dropped
  EXPECT_EQ(ring.dropped_bytes(), 0u);
  EXPECT_EQ(drain(&ring, &a), (std::vector<std::string>{r1, r2}));
  EXPECT_GE(fw::LineRing<fw::kBridgeRxRingBytes>::capacity_bytes(),
            fw::kBridgeRxQueuedRequests * fw::kLongestValidRequestLineBytes);
}

TEST(RxRing, ThirdQueuedRequestIsDroppedWholeAndTheNextOneIsKept) {
  // GIVEN the bridge ring with two queued requests, WHEN a third arrives before the main loop reads
  fw::LineRing<fw::kBridgeRxRingBytes> ring;
  fw::LineAssembler a;
  const std::string r1 = longest_request(1), r2 = longest_request(2), r3 = longest_request(3),
                    r4 = longest_request(4);
  push_all(&ring, r1 + "\r\n" + r2 + "\r\n" + r3 + "\r\n");
  std::vector<std::string> got = drain(&ring, &a);
  EXPECT_GT(ring.dropped_bytes(), 0u);
  // AND a request arriving after the ring drained
  push_all(&ring, r4 + "\n");
  const std::vector<std::string> tail = drain(&ring, &a);
  got.insert(got.end(), tail.begin(), tail.end());
  // THEN the third is dropped whole (its cut marker is placed once there is room, before the
  // fourth), no part of it reaches the assembler as a line, and the fourth is kept
  EXPECT_EQ(got, (std::vector<std::string>{r1, r2, "<dropped>", r4}));
}

struct CutRow {
  const char* name;
  std::string before_drain;  ///< bytes arriving while the consumer reads nothing
  std::string after_drain;   ///< bytes arriving after it read everything
  std::vector<std::string> want;
};

TEST(RxRing, SmallRingCutCasesTable) {
  // A 8-slot ring (7 bytes) makes every boundary reachable by hand.
  const std::vector<CutRow> rows = {
      {"GIVEN a line that fits exactly WHEN it arrives THEN it is kept",
       "abcdef\n",
       "gh\n",
       {"abcdef", "gh"}},
      {"GIVEN a line whose newline finds the ring full THEN it is dropped, the next kept",
       "abcdefg\n",
       "gh\n",
       {"<dropped>", "gh"}},
      {"GIVEN a line cut in the middle THEN it is dropped whole, the next kept",
       "ab\ncdefghij\n",
       "kl\n",
       {"ab", "<dropped>", "kl"}},
      {"GIVEN a cut line whose marker finds no room THEN the following line goes too, one marker",
       "abcdefghij\nklm\n",
       "no\n",
       {"<dropped>", "no"}},
  };
  for (const auto& r : rows) {
    fw::LineRing<8> ring;
    fw::LineAssembler a;
    push_all(&ring, r.before_drain);
    std::vector<std::string> got = drain(&ring, &a);
    push_all(&ring, r.after_drain);
    const std::vector<std::string> tail = drain(&ring, &a);
    got.insert(got.end(), tail.begin(), tail.end());
    EXPECT_EQ(got, r.want) << r.name;
  }
}

TEST(RxRing, CutMarkerEndsTheDiscardingOfAnOverlongLine) {
  // GIVEN the assembler discarding an over-long line (answered 414) whose newline is lost in a full
  // ring, together with the next line
  fw::LineRing<8> ring;
  fw::LineAssembler a;
  for (size_t i = 0; i < fw::kMaxRequestBytes; ++i) a.feed('x', 0);
  ASSERT_EQ(a.feed('x', 0), fw::LineEvent::kTooLong);
  push_all(&ring, std::string(20, 'x') + "\nok\n");
  EXPECT_EQ(drain(&ring, &a), std::vector<std::string>{});
  // WHEN the next line arrives after the ring drained
  push_all(&ring, "ok\n");
  // THEN the marker ends the discarding and the new line is kept
  EXPECT_EQ(drain(&ring, &a), (std::vector<std::string>{"<dropped>", "ok"}));
  EXPECT_FALSE(a.discarding());
}

TEST(RxRing, RandomBurstsAndReadPausesNeverSpliceLines) {
  // GIVEN a stream of distinct lines pushed into the bridge ring while the consumer reads in
  // bursts separated by random pauses (seeded), WHEN everything is drained
  fw::LineRing<fw::kBridgeRxRingBytes> ring;
  fw::LineAssembler a;
  uint32_t lcg = 12345;
  auto rnd = [&lcg](uint32_t n) {
    lcg = lcg * 1664525u + 1013904223u;
    return (lcg >> 8) % n;
  };
  std::vector<std::string> sent;
  std::vector<std::string> got;
  uint8_t b;
  for (uint32_t id = 0; id < 2000; ++id) {
    std::string line = longest_request(id).substr(0, 40 + rnd(54));
    sent.push_back(line);
    for (char c : line + "\n") {
      ring.push_line_byte(static_cast<uint8_t>(c));
      // the consumer takes 0..2 bytes per arriving byte: sometimes slower than the line
      for (uint32_t k = rnd(3); k > 0 && ring.pop(&b);) {
        --k;
        const fw::LineEvent e = a.feed(b, 0);
        if (e == fw::LineEvent::kLine) got.emplace_back(a.line(), a.length());
      }
    }
  }
  const std::vector<std::string> rest = drain(&ring, &a);
  for (const auto& s : rest) {
    if (s != "<dropped>") got.push_back(s);
  }
  // THEN every line that came out is one that went in, whole, in order (some were dropped)
  size_t i = 0;
  for (const auto& g : got) {
    while (i < sent.size() && sent[i] != g) ++i;
    ASSERT_LT(i, sent.size()) << "spliced or reordered line: " << g;
    ++i;
  }
  EXPECT_GT(got.size(), 100u);
  EXPECT_LT(got.size(), sent.size());
}

}  // namespace
