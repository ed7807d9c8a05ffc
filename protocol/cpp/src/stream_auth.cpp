// Stream authentication tags and key files: see stream_auth.hpp.
#include "rgbdquad/protocol/stream_auth.hpp"

#include <sys/random.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "rgbd_control/siphash24.h"
#include "rgbdquad/protocol/codec.hpp"

namespace rgbdquad::protocol {
namespace {

static_assert(kStreamAuthKeyBytes == rgbd_control::kSipHashKeyBytes,
              "the spec's key is a SipHash key");
static_assert(kStreamAuthTagBytes == rgbd_control::kSipHashTagBytes,
              "the spec's tag is a SipHash tag");

// A key file larger than this is not a key file (32 hex digits and a newline).
constexpr std::size_t kMaxKeyFileBytes = 256;

StreamTag tag_of(const StreamKey& key, const std::vector<std::uint8_t>& message) {
  StreamTag tag{};
  rgbd_control::siphash24_tag_bytes(
      rgbd_control::siphash24(key.data(), message.data(), message.size()), tag.data());
  return tag;
}

void append(std::vector<std::uint8_t>& out, std::string_view label) {
  out.insert(out.end(), label.begin(), label.end());
}
void append(std::vector<std::uint8_t>& out, const StreamNonce& nonce) {
  out.insert(out.end(), nonce.begin(), nonce.end());
}

// The body as encode_body() writes it; a message the codec refuses gives an empty body, whose
// tag then matches no tag a valid peer computed (the decoder never delivers such a message).
void append_body(std::vector<std::uint8_t>& out, const Message& m) {
  const EncodeResult body = encode_body(m);
  out.insert(out.end(), body.bytes.begin(), body.bytes.end());
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

StreamTag handshake_tag(const StreamKey& key, const StreamNonce& receiver_nonce,
                        const Handshake& hello) {
  Handshake unsigned_hello = hello;
  unsigned_hello.mac = {};
  std::vector<std::uint8_t> message;
  append(message, kStreamAuthHandshakeLabel);
  append(message, receiver_nonce);
  append_body(message, unsigned_hello);
  return tag_of(key, message);
}

StreamTag ack_tag(const StreamKey& key, const StreamNonce& receiver_nonce,
                  const StreamNonce& sender_nonce, const HandshakeAck& ack) {
  HandshakeAck unsigned_ack = ack;
  unsigned_ack.mac = {};
  std::vector<std::uint8_t> message;
  append(message, kStreamAuthAckLabel);
  append(message, receiver_nonce);
  append(message, sender_nonce);
  append_body(message, unsigned_ack);
  return tag_of(key, message);
}

bool tags_equal(const StreamTag& a, const StreamTag& b) {
  std::uint8_t diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff = static_cast<std::uint8_t>(diff | (a[i] ^ b[i]));
  return diff == 0;
}

StreamNonce random_stream_nonce() {
  StreamNonce nonce{};
  std::size_t filled = 0;
  while (filled < nonce.size()) {
    const ssize_t got = ::getrandom(nonce.data() + filled, nonce.size() - filled, 0);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) throw std::runtime_error(std::string("getrandom: ") + std::strerror(errno));
    filled += static_cast<std::size_t>(got);
  }
  return nonce;
}

std::optional<StreamKey> parse_stream_key(std::string_view text, std::string* error) {
  const auto first = text.find_first_not_of(" \t\r\n");
  const auto last = text.find_last_not_of(" \t\r\n");
  const std::string_view hex =
      first == std::string_view::npos ? std::string_view{} : text.substr(first, last - first + 1);
  if (hex.size() != 2 * kStreamAuthKeyBytes) {
    *error = "a stream key is " + std::to_string(2 * kStreamAuthKeyBytes) + " hex digits, found " +
             std::to_string(hex.size()) + " characters";
    return std::nullopt;
  }
  StreamKey key{};
  bool all_zero = true;
  for (std::size_t i = 0; i < key.size(); ++i) {
    const int hi = hex_digit(hex[2 * i]);
    const int lo = hex_digit(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) {
      *error = "a stream key is hex digits only (0-9, a-f)";
      return std::nullopt;
    }
    key[i] = static_cast<std::uint8_t>(hi << 4 | lo);
    all_zero = all_zero && key[i] == 0;
  }
  if (all_zero) {
    *error =
        "the stream key is all zeros (an unfilled template; generate one with `openssl rand -hex "
        "16`)";
    return std::nullopt;
  }
  return key;
}

std::optional<StreamKey> load_stream_key_file(const std::string& path, std::string* error) {
  const std::string fix = " (create it with `(umask 077; openssl rand -hex 16 > " + path +
                          ")` and copy the same file to the other end of the stream)";
  if (path.empty()) {
    *error = "no stream key file configured";
    return std::nullopt;
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    *error = "stream key file " + path + ": " + std::strerror(errno) + fix;
    return std::nullopt;
  }
  if (!S_ISREG(st.st_mode)) {
    *error = "stream key file " + path + " is not a regular file";
    return std::nullopt;
  }
  if ((st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    *error = "stream key file " + path + " is accessible by group or others (mode " + mode +
             "); `chmod 600 " + path + "`";
    return std::nullopt;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = "stream key file " + path + ": cannot be read";
    return std::nullopt;
  }
  std::string text(kMaxKeyFileBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (text.size() > kMaxKeyFileBytes) {
    *error = "stream key file " + path + " is larger than a key";
    return std::nullopt;
  }
  std::string why;
  auto key = parse_stream_key(text, &why);
  if (!key) *error = "stream key file " + path + ": " + why;
  return key;
}

}  // namespace rgbdquad::protocol
