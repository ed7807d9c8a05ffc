// McapWriter: byte layout of the parts a reader checks first (magic, Header, Footer, DataEnd CRC),
// failure behaviour on a write error. Full-file validation is the Python `mcap` reader's job
// (test_mcap_writer.py).
#include "rgbdquad/recorder/mcap_writer.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <zlib.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace {
using rgbdquad::recorder::McapWriter;
using rgbdquad::recorder::McapWriterOptions;

std::string read_all(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}
std::uint64_t u64_at(const std::string& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}
std::uint32_t u32_at(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}
std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("mcap_writer_test_" + std::to_string(::getpid()) + "_" + name))
      .string();
}
const std::string kMagic("\x89MCAP0\r\n", 8);

TEST(McapWriter, GivenMessagesWhenClosedThenMagicHeaderFooterAndDataCrcAreAsSpecified) {
  for (const bool zstd : {false, true}) {
    const std::string path = temp_path(zstd ? "zstd.mcap" : "plain.mcap");
    std::string error;
    McapWriterOptions o;
    o.zstd = zstd;
    auto w = McapWriter::open(path, o, &error);
    ASSERT_TRUE(w) << error;
    const auto s = w->add_schema("s", "jsonschema", "{}");
    const auto c = w->add_channel(s, "/t", "json");
    EXPECT_EQ(s, 1);
    EXPECT_EQ(c, 1);
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(w->write_message(c, i, 1000u * i, 1000u * i, "{}"));
    ASSERT_TRUE(w->close()) << w->error();
    const std::string b = read_all(path);
    ASSERT_GT(b.size(), 2 * kMagic.size() + 29);
    EXPECT_EQ(b.substr(0, 8), kMagic);
    EXPECT_EQ(b.substr(b.size() - 8), kMagic);
    EXPECT_EQ(b[8], '\x01');  // Header opcode
    // Footer: opcode 0x02, length 20, summary_start, summary_offset_start, summary_crc; then magic.
    const std::size_t footer = b.size() - 8 - 29;
    EXPECT_EQ(b[footer], '\x02');
    EXPECT_EQ(u64_at(b, footer + 1), 20u);
    const std::uint64_t summary_start = u64_at(b, footer + 9);
    ASSERT_GT(summary_start, 13u);
    // DataEnd (opcode 0x0F, length 4) ends right where the summary starts; its CRC covers all
    // before it.
    const std::size_t data_end = summary_start - 13;
    EXPECT_EQ(b[data_end], '\x0f');
    const auto crc = static_cast<std::uint32_t>(
        crc32(0, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(data_end)));
    EXPECT_EQ(u32_at(b, data_end + 9), crc);
    const auto summary_crc = static_cast<std::uint32_t>(
        crc32(0, reinterpret_cast<const Bytef*>(b.data() + summary_start),
              static_cast<uInt>(footer + 25 - summary_start)));
    EXPECT_EQ(u32_at(b, footer + 25), summary_crc);
    std::filesystem::remove(path);
  }
}

TEST(McapWriter, GivenAFileSizeLimitWhenExceededThenTheWriterFailsWithTheCauseAndStaysFailed) {
  const std::string path = temp_path("limit.mcap");
  rlimit old{};
  getrlimit(RLIMIT_FSIZE, &old);
  auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit lim{4096, old.rlim_max};
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &lim), 0);
  std::string error;
  McapWriterOptions o;
  o.zstd = false;
  o.chunk_max_bytes = 1024;
  auto w = McapWriter::open(path, o, &error);
  ASSERT_TRUE(w) << error;
  const auto c = w->add_channel(w->add_schema("s", "jsonschema", "{}"), "/t", "json");
  bool failed_at_some_point = false;
  for (int i = 0; i < 200 && !failed_at_some_point; ++i) {
    failed_at_some_point = !w->write_message(c, i, i, i, std::string(100, 'x'));
  }
  setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_TRUE(failed_at_some_point);
  EXPECT_TRUE(w->failed());
  EXPECT_NE(w->error().find("File too large"), std::string::npos) << w->error();
  EXPECT_FALSE(w->write_message(c, 0, 0, 0, "{}"));
  EXPECT_FALSE(w->close());
  EXPECT_LE(std::filesystem::file_size(path), 4096u);
  std::filesystem::remove(path);
}

TEST(McapWriter, GivenAnUnwritableFolderWhenOpenedThenTheErrorNamesThePath) {
  std::string error;
  EXPECT_FALSE(McapWriter::open("/nonexistent-dir/x.mcap", {}, &error));
  EXPECT_NE(error.find("/nonexistent-dir/x.mcap"), std::string::npos);
}
}  // namespace
