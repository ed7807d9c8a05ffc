// Replays every golden vector of protocol/vectors/manifest.json through the C++ StreamDecoder, fed
// whole, byte by byte and in 7-byte chunks, and compares the events with the manifest (the same
// expectations the Python codec is held to). Valid vectors must also re-encode to the same bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <set>

#include "json_view.hpp"
#include "rgbdquad/protocol/codec.hpp"
#include "rgbdquad/protocol/stream_auth.hpp"

namespace rgbdquad::protocol {
namespace {

using nlohmann::json;

const std::string kVectorsDir = RGBD_PROTOCOL_VECTORS_DIR;

json load_manifest() {
  std::ifstream in(kVectorsDir + "/manifest.json");
  if (!in) return json();
  return json::parse(in);
}

std::vector<std::uint8_t> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Same merge as rgbd_protocol.codec.normalize_events.
json normalize(const json& events) {
  json out = json::array();
  for (const json& e : events) {
    if (e.value("error", "") == "garbage_skipped" && !out.empty() &&
        out.back()["event"] == "error") {
      out.back()["bytes_discarded"] = out.back()["bytes_discarded"].get<std::size_t>() +
                                      e["bytes_discarded"].get<std::size_t>();
    } else {
      out.push_back(e);
    }
  }
  return out;
}

struct Replay {
  json events = json::array();
  std::size_t buffered = 0;
  std::vector<Message> messages;
  std::vector<unsigned> versions;  ///< envelope version of each message
};

Replay replay(const std::vector<std::uint8_t>& data, std::size_t chunk) {
  Replay r;
  StreamDecoder decoder;
  if (chunk == 0) chunk = data.empty() ? 1 : data.size();
  for (std::size_t off = 0; off < data.size(); off += chunk) {
    decoder.feed(data.data() + off, std::min(chunk, data.size() - off));
    for (DecodeResult d = decoder.next(); d.status != DecodeStatus::kNeedMoreBytes;
         d = decoder.next()) {
      if (d.status == DecodeStatus::kMessage) {
        r.events.push_back({{"event", "message"}, {"message", to_json(*d.message)}});
        r.messages.push_back(*d.message);
        r.versions.push_back(d.version);
      } else {
        r.events.push_back({{"event", "error"},
                            {"error", to_string(d.error)},
                            {"bytes_discarded", d.bytes_discarded}});
      }
    }
  }
  r.events = normalize(r.events);
  r.buffered = decoder.buffered_bytes();
  return r;
}

TEST(GoldenVectors, ManifestIsPresentAndForThisSchema) {
  const json manifest = load_manifest();
  ASSERT_TRUE(manifest.is_object()) << "missing " << kVectorsDir << "/manifest.json";
  char hash[32];
  std::snprintf(hash, sizeof hash, "0x%016llx", static_cast<unsigned long long>(kSchemaHash));
  EXPECT_EQ(manifest["schema_hash"], hash)
      << "vectors were generated from another spec: run python3 protocol/tools/make_vectors.py";
  EXPECT_GE(manifest["vectors"].size(), 40u);
}

TEST(GoldenVectors, EveryVectorGivesTheExpectedEventsForAnyChunking) {
  const json manifest = load_manifest();
  ASSERT_TRUE(manifest.is_object());
  for (const json& v : manifest["vectors"]) {
    const std::string name = v["name"];
    const auto data = read_file(kVectorsDir + "/" + v["file"].get<std::string>());
    for (std::size_t chunk : {std::size_t{0}, std::size_t{1}, std::size_t{7}}) {
      const Replay r = replay(data, chunk);
      EXPECT_EQ(r.events, v["expected"]["events"]) << name << " chunk " << chunk;
      EXPECT_EQ(r.buffered, v["expected"]["buffered_bytes"].get<std::size_t>())
          << name << " chunk " << chunk;
    }
  }
}

TEST(GoldenVectors, ValidVectorsReencodeToTheSameBytes) {
  const json manifest = load_manifest();
  ASSERT_TRUE(manifest.is_object());
  int checked = 0;
  for (const json& v : manifest["vectors"]) {
    if (!v["reencodes_to_same_bytes"].get<bool>()) continue;
    const auto data = read_file(kVectorsDir + "/" + v["file"].get<std::string>());
    std::vector<std::uint8_t> again;
    const Replay r = replay(data, 0);
    for (std::size_t i = 0; i < r.messages.size(); ++i) {
      // Each message re-encodes in the envelope version it came in (an older peer's included).
      const Message& m = r.messages[i];
      const EncodeResult e = encode(m, r.versions[i]);
      ASSERT_TRUE(e.ok()) << v["name"] << ": " << e.error;
      again.insert(again.end(), e.bytes.begin(), e.bytes.end());
      // The JSON view round-trips too (what the cross-language tool relies on).
      const EncodeResult from_view = encode(message_from_json(to_json(m)), r.versions[i]);
      EXPECT_EQ(from_view.bytes, e.bytes) << v["name"];
    }
    EXPECT_EQ(again, data) << v["name"];
    ++checked;
  }
  EXPECT_GE(checked, 20);
}

TEST(GoldenVectors, RefusedPeersAreRefusedWithTheStatedReason) {
  const json manifest = load_manifest();
  ASSERT_TRUE(manifest.is_object());
  int checked = 0;
  for (const json& v : manifest["vectors"]) {
    const auto data = read_file(kVectorsDir + "/" + v["file"].get<std::string>());
    for (const Message& m : replay(data, 0).messages) {
      std::string reason;
      if (const auto* h = std::get_if<Handshake>(&m)) reason = handshake_incompatibility(*h);
      if (const auto* h = std::get_if<SlamHello>(&m)) reason = hello_incompatibility(*h);
      if (v.contains("refused")) {
        EXPECT_NE(reason.find(v["refused"].get<std::string>()), std::string::npos)
            << v["name"] << ": '" << reason << "'";
        ++checked;
      } else {
        EXPECT_EQ(reason, "") << v["name"];
      }
    }
  }
  EXPECT_EQ(checked, 4);  // wrong hash, wrong version, old version with the new hash, SLAM hello
}

template <typename Array>
Array array_from_hex(const json& hex) {
  const auto bytes = from_hex(hex.get<std::string>());
  Array out{};
  EXPECT_EQ(bytes.size(), out.size());
  std::copy_n(bytes.begin(), std::min(bytes.size(), out.size()), out.begin());
  return out;
}

// Every signed Handshake/HandshakeAck in the vectors verifies under the manifest's key and nonces
// (the Python generator computed the tags: this is the cross-language check of the MAC), the
// forged ones do not, and a wrong key or another challenge never verifies.
TEST(GoldenVectors, StreamAuthTagsOfTheVectors) {
  const json manifest = load_manifest();
  ASSERT_TRUE(manifest.is_object() && manifest.contains("stream_auth"));
  const json& auth = manifest["stream_auth"];
  const auto key = array_from_hex<StreamKey>(auth["key"]);
  const auto receiver_nonce = array_from_hex<StreamNonce>(auth["receiver_nonce"]);
  const auto sender_nonce = array_from_hex<StreamNonce>(auth["sender_nonce"]);
  StreamKey other_key = key;
  other_key[15] ^= 0x80;
  StreamNonce other_nonce = receiver_nonce;
  other_nonce[0] ^= 1;
  std::set<std::string> forged;
  for (const json& name : auth["forged"]) forged.insert(name.get<std::string>());
  int signed_checked = 0;
  int forged_checked = 0;
  for (const json& v : manifest["vectors"]) {
    const std::string name = v["name"];
    const auto data = read_file(kVectorsDir + "/" + v["file"].get<std::string>());
    for (const Message& m : replay(data, 0).messages) {
      bool ok = false;
      bool ok_other_key = false;
      bool ok_other_nonce = false;
      if (const auto* h = std::get_if<Handshake>(&m)) {
        ok = tags_equal(h->mac, handshake_tag(key, receiver_nonce, *h));
        ok_other_key = tags_equal(h->mac, handshake_tag(other_key, receiver_nonce, *h));
        ok_other_nonce = tags_equal(h->mac, handshake_tag(key, other_nonce, *h));
      } else if (const auto* a = std::get_if<HandshakeAck>(&m)) {
        ok = tags_equal(a->mac, ack_tag(key, receiver_nonce, sender_nonce, *a));
        ok_other_key = tags_equal(a->mac, ack_tag(other_key, receiver_nonce, sender_nonce, *a));
        ok_other_nonce = tags_equal(a->mac, ack_tag(key, receiver_nonce, other_nonce, *a));
      } else {
        continue;
      }
      EXPECT_EQ(ok, forged.count(name) == 0) << name;
      EXPECT_FALSE(ok_other_key) << name;
      EXPECT_FALSE(ok_other_nonce) << name;
      ++(ok ? signed_checked : forged_checked);
    }
  }
  EXPECT_GE(signed_checked, 8);
  EXPECT_EQ(forged_checked, 2);
}

TEST(StreamKey, ParsesHexAndRefusesEverythingElse) {
  std::string error;
  const auto key = parse_stream_key("  000102030405060708090a0b0c0d0eFF\n", &error);
  ASSERT_TRUE(key) << error;
  EXPECT_EQ((*key)[15], 0xFF);
  for (const char* bad : {"", "0001", "000102030405060708090a0b0c0d0e0f00",
                          "g00102030405060708090a0b0c0d0e0f", "00000000000000000000000000000000"}) {
    error.clear();
    EXPECT_FALSE(parse_stream_key(bad, &error)) << bad;
    EXPECT_FALSE(error.empty()) << bad;
  }
}

}  // namespace
}  // namespace rgbdquad::protocol
