// A small MCAP writer (https://mcap.dev/spec, version 0 "MCAP0"), written to the published format
// spec because no C++ MCAP library is packaged for Debian 12. Every file it writes is validated by
// the Python `mcap` reader in tests (offboard/recorder/tests/).
//
// Layout written:
//   magic, Header, Schema*, Channel*,                      (data section, written at open)
//   { Chunk (zstd or uncompressed, CRC32 of its records), MessageIndex per channel }*,
//   DataEnd (CRC32 of everything before it),
//   Summary: Schema*, Channel*, Statistics, ChunkIndex*; SummaryOffset per group; Footer; magic.
//
// Crash safety: messages are buffered in the open chunk only; flush_chunk() writes the chunk and
// its message indexes with write(2) (no user-space buffer), so a process killed after it returns
// leaves every flushed chunk readable by a streaming reader. The caller flushes about once a
// second; close() writes the summary. A write error (ENOSPC, EFBIG, EIO) makes the writer failed:
// every later call returns false and error() says why; the file up to the last good chunk stays.
//
// Time stamps are nanoseconds (MCAP's unit); which clock is the caller's business.
// Not thread-safe: one writer thread owns it.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace rgbdquad::recorder {

struct McapWriterOptions {
  std::string profile;  ///< MCAP profile ("" = none; ours is JSON-encoded messages)
  std::string library = "rgbdquad-recorder";
  bool zstd = true;  ///< compress chunks with zstd (level 1: fast)
  /// A chunk is closed when its records exceed this (also on flush_chunk()). 4 MiB: a few image
  /// messages per chunk; readers decompress one chunk at a time.
  std::size_t chunk_max_bytes = 4u << 20;
  /// True when every field is in range; else false and, if error is not null, which one and why.
  bool is_valid(std::string* error) const;
};

class McapWriter {
 public:
  /// Creates (truncates) `path` and writes magic + Header. nullptr with `error` on failure.
  static std::unique_ptr<McapWriter> open(const std::string& path, McapWriterOptions options,
                                          std::string* error);
  ~McapWriter();  ///< close()s if not closed (errors then only in error())
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Schema / channel records go straight into the data section (before any message that uses
  /// them), so a streaming reader of a truncated file knows every channel. Ids start at 1. 0 on
  /// failure.
  std::uint16_t add_schema(const std::string& name, const std::string& encoding,
                           const std::string& data);
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic,
                            const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  /// Appends a message to the open chunk (closing it first when full). False once failed.
  bool write_message(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time_ns,
                     std::uint64_t publish_time_ns, const std::string& data);
  /// Writes the open chunk (if any message) and its message indexes. False once failed.
  bool flush_chunk();
  /// Flushes, writes DataEnd, the summary and the footer, closes the file. Idempotent.
  bool close();

  bool failed() const { return !error_.empty(); }
  const std::string& error() const { return error_; }
  /// Bytes in the file so far plus the open chunk's records (what close() would roughly leave).
  std::uint64_t size_bytes() const { return file_offset_ + chunk_records_.size(); }
  std::uint64_t message_count() const { return message_count_; }
  const std::string& path() const { return path_; }

 private:
  McapWriter(std::string path, int fd, McapWriterOptions options);
  struct ChunkIndexEntry {
    std::uint64_t start_ns, end_ns, offset, length, index_length, compressed, uncompressed;
    std::map<std::uint16_t, std::uint64_t> index_offsets;
  };
  bool write_out(
      const std::string& bytes);  ///< to the file, data CRC updated; sets error_ on failure

  std::string path_;
  int fd_;
  McapWriterOptions options_;
  std::string error_;
  bool closed_ = false;
  std::uint64_t file_offset_ = 0;
  std::uint32_t data_crc_ = 0;
  std::vector<std::string> schema_records_, channel_records_;
  std::uint16_t next_schema_id_ = 1, next_channel_id_ = 1;
  // Open chunk.
  std::string chunk_records_;
  std::uint64_t chunk_start_ns_ = 0, chunk_end_ns_ = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>>
      chunk_index_;  ///< (log time, offset)
  // Summary.
  std::vector<ChunkIndexEntry> chunks_;
  std::uint64_t message_count_ = 0, message_start_ns_ = 0, message_end_ns_ = 0;
  std::map<std::uint16_t, std::uint64_t> channel_counts_;
};

}  // namespace rgbdquad::recorder
