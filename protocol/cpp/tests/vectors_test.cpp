// Replays every golden vector of protocol/vectors/manifest.json through the C++ StreamDecoder, fed
// whole, byte by byte and in 7-byte chunks, and compares the events with the manifest (the same
// expectations the Python codec is held to). Valid vectors must also re-encode to the same bytes.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "json_view.hpp"
#include "rgbdquad/protocol/codec.hpp"

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
    for (const Message& m : replay(data, 0).messages) {
      const EncodeResult e = encode(m);
      ASSERT_TRUE(e.ok()) << v["name"] << ": " << e.error;
      again.insert(again.end(), e.bytes.begin(), e.bytes.end());
      // The JSON view round-trips too (what the cross-language tool relies on).
      const EncodeResult from_view = encode(message_from_json(to_json(m)));
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
  EXPECT_EQ(checked, 3);
}

}  // namespace
}  // namespace rgbdquad::protocol
