// rgbd-protocol-tool: encode and decode protocol messages from the command line. The Python
// cross-language tests drive it (Python encodes -> this decodes, and the reverse); it is also handy
// for looking at a captured byte stream.
#include <cstdio>
#include <cstring>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

#include "json_view.hpp"
#include "rgbdquad/protocol/codec.hpp"

namespace {

namespace proto = rgbdquad::protocol;

constexpr const char* kUsage =
    "usage: rgbd-protocol-tool COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  encode              read message views (JSON, one per line: {\"type\":..,\"fields\":{..}})\n"
    "                      from stdin, write their envelopes (binary) to stdout\n"
    "  decode [--chunk N]  read a byte stream from stdin, feed it to the StreamDecoder N bytes at\n"
    "                      a time (default: all at once) and print one JSON line per event:\n"
    "                      {\"event\":\"message\",\"message\":{..}} or\n"
    "                      "
    "{\"event\":\"error\",\"error\":name,\"bytes_discarded\":n,\"detail\":..},\n"
    "                      then {\"event\":\"end\",\"buffered_bytes\":n}\n"
    "  schema-hash         print the schema hash and protocol version this build speaks\n"
    "  --help              this text\n"
    "\n"
    "exit status: 0 success, 1 a message failed to encode (reason on stderr), 2 usage error\n";

std::vector<std::uint8_t> read_stdin_bytes() {
  std::vector<std::uint8_t> bytes;
  std::uint8_t buf[65536];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, stdin)) > 0) bytes.insert(bytes.end(), buf, buf + n);
  return bytes;
}

int run_encode() {
  std::string line;
  int line_no = 0;
  while (std::getline(std::cin, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    try {
      const auto view = nlohmann::json::parse(line);
      const proto::EncodeResult encoded = proto::encode(proto::message_from_json(view));
      if (!encoded.ok()) {
        std::cerr << "line " << line_no << ": invalid message: " << encoded.error << "\n";
        return 1;
      }
      std::fwrite(encoded.bytes.data(), 1, encoded.bytes.size(), stdout);
    } catch (const std::exception& e) {  // start-up style boundary: bad user input
      std::cerr << "line " << line_no << ": " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}

int run_decode(std::size_t chunk) {
  const std::vector<std::uint8_t> bytes = read_stdin_bytes();
  proto::StreamDecoder decoder;
  auto drain = [&decoder]() {
    for (;;) {
      proto::DecodeResult r = decoder.next();
      if (r.status == proto::DecodeStatus::kNeedMoreBytes) return;
      nlohmann::json event;
      if (r.status == proto::DecodeStatus::kMessage) {
        event = {{"event", "message"}, {"message", proto::to_json(*r.message)}};
      } else {
        event = {{"event", "error"},
                 {"error", proto::to_string(r.error)},
                 {"bytes_discarded", r.bytes_discarded},
                 {"detail", r.detail}};
      }
      std::cout << event.dump() << "\n";
    }
  };
  if (chunk == 0) chunk = bytes.size();
  for (std::size_t off = 0; off < bytes.size(); off += chunk) {
    decoder.feed(bytes.data() + off, std::min(chunk, bytes.size() - off));
    drain();
  }
  std::cout << nlohmann::json{{"event", "end"}, {"buffered_bytes", decoder.buffered_bytes()}}.dump()
            << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << kUsage;
    return 2;
  }
  const std::string command = argv[1];
  if (command == "--help" || command == "-h" || command == "help") {
    std::cout << kUsage;
    return 0;
  }
  if (command == "encode" && argc == 2) return run_encode();
  if (command == "decode") {
    std::size_t chunk = 0;
    if (argc == 4 && std::strcmp(argv[2], "--chunk") == 0) {
      char* end = nullptr;
      const unsigned long long v = std::strtoull(argv[3], &end, 10);
      if (end == argv[3] || *end != '\0' || v == 0) {
        std::cerr << "decode: --chunk needs a positive integer\n";
        return 2;
      }
      chunk = static_cast<std::size_t>(v);
    } else if (argc != 2) {
      std::cerr << kUsage;
      return 2;
    }
    return run_decode(chunk);
  }
  if (command == "schema-hash" && argc == 2) {
    std::printf("schema_hash 0x%016llx\nprotocol_version %u\n",
                static_cast<unsigned long long>(proto::kSchemaHash),
                static_cast<unsigned>(proto::kProtocolVersion));
    return 0;
  }
  std::cerr << "unknown command or arguments\n" << kUsage;
  return 2;
}
