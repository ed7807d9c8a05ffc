// MCAP writer: see mcap_writer.hpp. Field order and opcodes follow https://mcap.dev/spec (v0).
#include "rgbdquad/recorder/mcap_writer.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>
#include <utility>

namespace rgbdquad::recorder {

namespace {

/// The failure path of is_valid(): stores `message` in *error unless error is null; false.
bool reject(std::string* error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

// MCAP opcodes (spec "Records").
enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};
constexpr char kMagic[8] = {'\x89', 'M', 'C', 'A', 'P', '0', '\r', '\n'};
// zstd level 1: the fastest standard level; images are already compressed (JPEG) or are 16-bit
// depth, where level 1 gets most of the gain (base64 text back to ~binary size, depth ~2-3x).
constexpr int kZstdLevel = 1;

// Explicit little-endian encoding (never memcpy of a struct).
void put_u8(std::string& b, std::uint8_t v) { b.push_back(static_cast<char>(v)); }
void put_u16(std::string& b, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u32(std::string& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u64(std::string& b, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_str(std::string& b, const std::string& s) {
  put_u32(b, static_cast<std::uint32_t>(s.size()));
  b += s;
}
std::string record(std::uint8_t op, const std::string& content) {
  std::string r;
  r.reserve(9 + content.size());
  put_u8(r, op);
  put_u64(r, content.size());
  r += content;
  return r;
}
std::uint32_t crc32_of(std::uint32_t crc, const std::string& bytes) {
  // zlib's crc32 is the CRC-32 (ISO-HDLC) the spec names; fed in <= 1 GiB pieces (uInt).
  const auto* p = reinterpret_cast<const Bytef*>(bytes.data());
  std::size_t left = bytes.size();
  while (left > 0) {
    const auto n = static_cast<uInt>(std::min<std::size_t>(left, 1u << 30));
    crc = static_cast<std::uint32_t>(::crc32(crc, p, n));
    p += n;
    left -= n;
  }
  return crc;
}
}  // namespace

bool McapWriterOptions::is_valid(std::string* error) const {
  if (chunk_max_bytes < 1024 || chunk_max_bytes > (256u << 20))
    return reject(error, "recorder: chunk_max_bytes must be in [1 KiB, 256 MiB]");
  return true;
}

std::unique_ptr<McapWriter> McapWriter::open(const std::string& path, McapWriterOptions options,
                                             std::string* error) {
  if (!options.is_valid(error)) return nullptr;
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    *error = "cannot create " + path + ": " + std::strerror(errno);
    return nullptr;
  }
  std::unique_ptr<McapWriter> w(new McapWriter(path, fd, std::move(options)));
  std::string header;
  put_str(header, w->options_.profile);
  put_str(header, w->options_.library);
  if (!w->write_out(std::string(kMagic, sizeof kMagic) + record(kHeader, header))) {
    *error = w->error_;
    return nullptr;
  }
  return w;
}

McapWriter::McapWriter(std::string path, int fd, McapWriterOptions options)
    : path_(std::move(path)), fd_(fd), options_(std::move(options)) {}

McapWriter::~McapWriter() {
  close();
  if (fd_ >= 0) ::close(fd_);
}

bool McapWriter::write_out(const std::string& bytes) {
  if (failed() || closed_) return false;
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error_ = "write to " + path_ +
               " failed: " + (n < 0 ? std::strerror(errno) : "no progress (disk full?)");
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  data_crc_ = crc32_of(data_crc_, bytes);
  file_offset_ += bytes.size();
  return true;
}

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding,
                                     const std::string& data) {
  if (next_schema_id_ == std::numeric_limits<std::uint16_t>::max()) return 0;
  const std::uint16_t id = next_schema_id_;
  std::string c;
  put_u16(c, id);
  put_str(c, name);
  put_str(c, encoding);
  put_str(c, data);  // uint32 length-prefixed bytes
  std::string r = record(kSchema, c);
  if (!write_out(r)) return 0;
  schema_records_.push_back(std::move(r));
  ++next_schema_id_;
  return id;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  if (next_channel_id_ == std::numeric_limits<std::uint16_t>::max()) return 0;
  const std::uint16_t id = next_channel_id_;
  std::string c;
  put_u16(c, id);
  put_u16(c, schema_id);
  put_str(c, topic);
  put_str(c, message_encoding);
  std::string map;
  for (const auto& [k, v] : metadata) {
    put_str(map, k);
    put_str(map, v);
  }
  put_u32(c, static_cast<std::uint32_t>(map.size()));
  c += map;
  std::string r = record(kChannel, c);
  if (!write_out(r)) return 0;
  channel_records_.push_back(std::move(r));
  channel_counts_[id] = 0;
  ++next_channel_id_;
  return id;
}

bool McapWriter::write_message(std::uint16_t channel_id, std::uint32_t sequence,
                               std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                               const std::string& data) {
  if (failed() || closed_) return false;
  if (!chunk_records_.empty() && chunk_records_.size() + data.size() > options_.chunk_max_bytes &&
      !flush_chunk()) {
    return false;
  }
  if (chunk_index_.empty()) {
    chunk_start_ns_ = log_time_ns;
    chunk_end_ns_ = log_time_ns;
  }
  chunk_start_ns_ = std::min(chunk_start_ns_, log_time_ns);
  chunk_end_ns_ = std::max(chunk_end_ns_, log_time_ns);
  chunk_index_[channel_id].emplace_back(log_time_ns, chunk_records_.size());
  std::string c;
  put_u16(c, channel_id);
  put_u32(c, sequence);
  put_u64(c, log_time_ns);
  put_u64(c, publish_time_ns);
  put_u8(chunk_records_, kMessage);
  put_u64(chunk_records_, c.size() + data.size());
  chunk_records_ += c;
  chunk_records_ += data;
  if (message_count_ == 0) message_start_ns_ = message_end_ns_ = log_time_ns;
  message_start_ns_ = std::min(message_start_ns_, log_time_ns);
  message_end_ns_ = std::max(message_end_ns_, log_time_ns);
  ++message_count_;
  ++channel_counts_[channel_id];
  return true;
}

bool McapWriter::flush_chunk() {
  if (failed() || closed_) return false;
  if (chunk_index_.empty()) return true;
  std::string compressed;
  std::string compression;
  if (options_.zstd) {
    compressed.resize(ZSTD_compressBound(chunk_records_.size()));
    const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_records_.data(),
                                        chunk_records_.size(), kZstdLevel);
    if (ZSTD_isError(n)) {
      error_ = std::string("zstd: ") + ZSTD_getErrorName(n);
      return false;
    }
    compressed.resize(n);
    compression = "zstd";
  }
  const std::string& body = options_.zstd ? compressed : chunk_records_;
  std::string c;
  put_u64(c, chunk_start_ns_);
  put_u64(c, chunk_end_ns_);
  put_u64(c, chunk_records_.size());
  put_u32(c, crc32_of(0, chunk_records_));
  put_str(c, compression);
  put_u64(c, body.size());
  c += body;
  ChunkIndexEntry entry{
      chunk_start_ns_, chunk_end_ns_, file_offset_, 0, 0, body.size(), chunk_records_.size(), {}};
  std::string out = record(kChunk, c);
  entry.length = out.size();
  for (const auto& [channel, entries] : chunk_index_) {
    std::string m;
    put_u16(m, channel);
    put_u32(m, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      put_u64(m, t);
      put_u64(m, off);
    }
    entry.index_offsets[channel] = file_offset_ + out.size();
    const std::string r = record(kMessageIndex, m);
    entry.index_length += r.size();
    out += r;
  }
  chunk_records_.clear();
  chunk_index_.clear();
  if (!write_out(out))
    return false;  // one write: a crash leaves the chunk whole or cut, never reordered
  chunks_.push_back(std::move(entry));
  return true;
}

bool McapWriter::close() {
  if (closed_) return !failed();
  if (failed()) {
    closed_ = true;
    return false;
  }
  if (!flush_chunk()) {
    closed_ = true;
    return false;
  }
  // DataEnd: CRC32 of every byte from the magic up to here.
  std::string de;
  put_u32(de, data_crc_);
  if (!write_out(record(kDataEnd, de))) {
    closed_ = true;
    return false;
  }
  const std::uint64_t summary_start = file_offset_;
  std::string summary;
  struct Group {
    std::uint8_t op;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  auto add_group = [&](std::uint8_t op, const std::vector<std::string>& records) {
    if (records.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const auto& r : records) summary += r;
    groups.push_back({op, start, summary_start + summary.size() - start});
  };
  add_group(kSchema, schema_records_);
  add_group(kChannel, channel_records_);
  std::string st;
  put_u64(st, message_count_);
  put_u16(st, static_cast<std::uint16_t>(schema_records_.size()));
  put_u32(st, static_cast<std::uint32_t>(channel_records_.size()));
  put_u32(st, 0);  // attachments
  put_u32(st, 0);  // metadata
  put_u32(st, static_cast<std::uint32_t>(chunks_.size()));
  put_u64(st, message_start_ns_);
  put_u64(st, message_end_ns_);
  std::string counts;
  for (const auto& [channel, n] : channel_counts_) {
    put_u16(counts, channel);
    put_u64(counts, n);
  }
  put_u32(st, static_cast<std::uint32_t>(counts.size()));
  st += counts;
  add_group(kStatistics, {record(kStatistics, st)});
  std::vector<std::string> chunk_index_records;
  for (const auto& e : chunks_) {
    std::string ci;
    put_u64(ci, e.start_ns);
    put_u64(ci, e.end_ns);
    put_u64(ci, e.offset);
    put_u64(ci, e.length);
    std::string offsets;
    for (const auto& [channel, off] : e.index_offsets) {
      put_u16(offsets, channel);
      put_u64(offsets, off);
    }
    put_u32(ci, static_cast<std::uint32_t>(offsets.size()));
    ci += offsets;
    put_u64(ci, e.index_length);
    put_str(ci, options_.zstd ? "zstd" : "");
    put_u64(ci, e.compressed);
    put_u64(ci, e.uncompressed);
    chunk_index_records.push_back(record(kChunkIndex, ci));
  }
  add_group(kChunkIndex, chunk_index_records);
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  std::string tail = summary;
  for (const auto& g : groups) {
    std::string so;
    put_u8(so, g.op);
    put_u64(so, g.start);
    put_u64(so, g.length);
    tail += record(kSummaryOffset, so);
  }
  // Footer; its CRC covers the summary, the summary offsets and the footer up to the CRC field.
  std::string footer_head;
  put_u8(footer_head, kFooter);
  put_u64(footer_head, 20);
  put_u64(footer_head, summary.empty() ? 0 : summary_start);
  put_u64(footer_head, summary_offset_start);
  tail += footer_head;
  const std::uint32_t summary_crc = crc32_of(0, tail);
  put_u32(tail, summary_crc);
  tail.append(kMagic, sizeof kMagic);
  const bool ok = write_out(tail);
  closed_ = true;
  if (fd_ >= 0) {
    if (::close(fd_) != 0 && ok) error_ = "close " + path_ + ": " + std::strerror(errno);
    fd_ = -1;
  }
  return ok && !failed();
}

}  // namespace rgbdquad::recorder
