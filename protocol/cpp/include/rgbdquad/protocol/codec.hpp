// Encoders and the incremental decoder of the shared envelope (docs/protocol.md, "Envelope"):
//   header (16 B: magic "RGBQ", version u8, type u8, reserved u16, body_length u32, header_crc32
//   u32) body (body_length B, fields little-endian in spec order) | trailer (body_crc32 u32)
// Pure functions and one value-owning class; no sockets, no clock, no globals. Every field is
// written explicitly little-endian (never a memcpy of a struct).
//
// Thread safety: free functions are reentrant; a StreamDecoder instance must be used by one thread
// at a time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "rgbdquad/protocol/messages.hpp"

namespace rgbdquad::protocol {

/// Why decoding failed. Stable names (to_string) are shared with the Python codec and the vectors.
enum class DecodeError : std::uint8_t {
  kNone = 0,
  kGarbageSkipped,      ///< bytes before a magic were discarded
  kBadHeaderCrc,        ///< header CRC mismatch (e.g. corrupt length); resynchronising
  kUnsupportedVersion,  ///< envelope version outside
                        ///< kOldestDecodedProtocolVersion..kProtocolVersion
  kUnknownMessageType,  ///< type id not in the spec
  kReservedNonzero,     ///< reserved header bits set
  kBodyTooLarge,        ///< body_length above the type's max_body_bytes (checked before waiting)
  kBadBodyCrc,          ///< body CRC mismatch; the whole frame is dropped
  kTruncatedBody,       ///< body shorter than its fields
  kLengthTooLarge,      ///< a string/bytes/array length prefix above its spec limit
  kTrailingBytes,       ///< body longer than its fields
  kInvalidValue,        ///< enum/bool/range/non-finite/consistency check failed
};
const char* to_string(DecodeError error);

/// Result of encoding: the complete envelope bytes, or why the message is invalid.
struct EncodeResult {
  std::vector<std::uint8_t> bytes;  ///< envelope + body + trailer; empty on error
  std::string error;                ///< empty on success
  bool ok() const { return error.empty(); }
};

/// Result of decoding one body (no envelope).
struct BodyResult {
  std::optional<Message> message;
  DecodeError error = DecodeError::kNone;
  std::string detail;  ///< human-readable reason, names the field
  bool ok() const { return message.has_value(); }
};

/// Encode a message into a full envelope of envelope version `version` (default: ours; an older
/// decoded version to answer a peer that speaks it: the fields that version lacks are left out).
/// Fails (error set) when the message breaks the spec (range, enum, length limits, RAW payload
/// size, ...): the same rules the decoder enforces; or for a version this build does not write.
EncodeResult encode(const Message& message, unsigned version = kProtocolVersion);

/// Convenience overloads (the same as encode(Message{...}) without the variant copy).
EncodeResult encode_handshake(const Handshake& message);
EncodeResult encode_handshake_ack(const HandshakeAck& message);
EncodeResult encode_frame(const Frame& message);
/// Frame from a header and payload bytes owned by the caller (header.payload_length must equal
/// payload_size) and the image's accelerometer sample. Avoids building a Frame for the sender's
/// hot path.
EncodeResult encode_frame(const FrameHeader& header, const std::uint8_t* payload,
                          std::size_t payload_size, const AccelSample& accel = {});
EncodeResult encode_frame_request(const FrameRequest& message);
EncodeResult encode_stream_challenge(const StreamChallenge& message);

/// Body of a message (no envelope) as `version` lays it out: what encode() wraps. Used by tests
/// and fuzzers.
EncodeResult encode_body(const Message& message, unsigned version = kProtocolVersion);

/// Spec checks of a message; empty string when valid, else the reason naming the field.
std::string validate(const Message& message);

/// Decode one body of the given wire type as envelope version `version` lays it out (fields that
/// version lacks keep their defaults). Never throws on hostile input; memory it allocates is
/// bounded by `size`.
BodyResult decode_body(std::uint8_t message_type, const std::uint8_t* data, std::size_t size,
                       unsigned version = kProtocolVersion);

/// Peer compatibility: empty when the handshake's version is one this build decodes and its schema
/// hash is that version's, else a reason to log loudly and to send back in HandshakeAck.
std::string handshake_incompatibility(const Handshake& peer);
std::string hello_incompatibility(const SlamHello& peer);

/// CRC-32 (IEEE 802.3, reflected, as zlib.crc32), continuing from `crc` (0 to start).
std::uint32_t crc32(const std::uint8_t* data, std::size_t size, std::uint32_t crc = 0);

enum class DecodeStatus : std::uint8_t {
  kNeedMoreBytes,  ///< feed more bytes
  kMessage,        ///< `message` holds a decoded message
  kError,          ///< `error` says what was dropped; call next() again
};

struct DecodeResult {
  DecodeStatus status = DecodeStatus::kNeedMoreBytes;
  std::optional<Message> message;
  DecodeError error = DecodeError::kNone;
  std::string detail;
  std::size_t bytes_discarded = 0;  ///< bytes dropped by this error (garbage, bad frame)
  /// Envelope version of `message`: a peer of an older version is answered in it.
  unsigned version = kProtocolVersion;
};

/// Incremental decoder of a byte stream of envelopes (one TCP connection).
/// Usage: feed() what the socket read, then call next() until it returns kNeedMoreBytes.
/// Resynchronises on the magic after garbage or a corrupt header; a bad body drops exactly one
/// frame. Header fields (CRC, version, type, body_length <= max) are checked before waiting for the
/// body, so a hostile length never makes it wait for or allocate more than max_body_bytes.
/// Memory: holds at most the bytes fed and not yet consumed.
class StreamDecoder {
 public:
  struct Options {
    /// Extra cap on body_length below the spec's per-type maximum (0 = spec maximum only), e.g.
    /// a stream receiver that never expects a FloorMap can cap at the Frame maximum.
    std::size_t max_body_bytes = 0;
  };

  StreamDecoder() = default;
  explicit StreamDecoder(Options options) : options_(options) {}

  void feed(const std::uint8_t* data, std::size_t size);
  void feed(const std::vector<std::uint8_t>& bytes) { feed(bytes.data(), bytes.size()); }
  DecodeResult next();
  /// Bytes fed and not yet consumed.
  std::size_t buffered_bytes() const { return buffer_.size() - read_offset_; }

 private:
  std::size_t discard_to_next_magic(std::size_t from);
  void consume(std::size_t count);

  Options options_;
  std::vector<std::uint8_t> buffer_;
  std::size_t read_offset_ = 0;
};

}  // namespace rgbdquad::protocol
