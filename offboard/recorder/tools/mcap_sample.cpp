// mcap-sample: writes a small MCAP file through rgbd_mcap for the Python reader's tests
// (offboard/recorder/tests/test_mcap_writer.py). Two JSON channels; message i on channel 1 + i % 2
// has log time i ms and payload {"i": i}.
//   mcap-sample OUT N [--no-zstd] [--flush-every K] [--no-close] [--fsize-limit BYTES]
//   [--chunk-bytes B]
// --no-close: flush, then _exit(0) without the summary (what a SIGKILL after a flush leaves).
// --fsize-limit: RLIMIT_FSIZE with SIGXFSZ ignored (a full disk); exit 3 with the writer's error.
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "rgbdquad/recorder/mcap_writer.hpp"

using rgbdquad::recorder::McapWriter;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: mcap-sample OUT N [--no-zstd] [--flush-every K] [--no-close] "
                 "[--fsize-limit B] [--chunk-bytes B]\n");
    return 2;
  }
  rgbdquad::recorder::McapWriterOptions options;
  long flush_every = 0, fsize_limit = 0;
  bool no_close = false;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-zstd")
      options.zstd = false;
    else if (a == "--no-close")
      no_close = true;
    else if (a == "--flush-every" && i + 1 < argc)
      flush_every = std::atol(argv[++i]);
    else if (a == "--fsize-limit" && i + 1 < argc)
      fsize_limit = std::atol(argv[++i]);
    else if (a == "--chunk-bytes" && i + 1 < argc)
      options.chunk_max_bytes = std::strtoul(argv[++i], nullptr, 10);
    else {
      std::fprintf(stderr, "mcap-sample: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (fsize_limit > 0) {
    std::signal(SIGXFSZ, SIG_IGN);  // write() then fails with EFBIG, as on a full disk
    rlimit lim{static_cast<rlim_t>(fsize_limit), static_cast<rlim_t>(fsize_limit)};
    setrlimit(RLIMIT_FSIZE, &lim);
  }
  std::string error;
  auto w = McapWriter::open(argv[1], options, &error);
  if (!w) {
    std::fprintf(stderr, "mcap-sample: %s\n", error.c_str());
    return 3;
  }
  const std::uint16_t schema = w->add_schema(
      "sample.Counter", "jsonschema", R"({"type":"object","properties":{"i":{"type":"integer"}}})");
  const std::uint16_t a = w->add_channel(schema, "/a", "json", {{"k", "v"}});
  const std::uint16_t b = w->add_channel(schema, "/b", "json");
  const long n = std::atol(argv[2]);
  for (long i = 0; i < n; ++i) {
    const std::uint64_t t_ns = static_cast<std::uint64_t>(i) * 1000000ULL;
    if (!w->write_message(i % 2 ? b : a, static_cast<std::uint32_t>(i / 2), t_ns, t_ns,
                          "{\"i\":" + std::to_string(i) + "}"))
      break;
    if (flush_every > 0 && (i + 1) % flush_every == 0 && !w->flush_chunk()) break;
  }
  if (no_close) {
    if (!w->flush_chunk()) {
      std::fprintf(stderr, "mcap-sample: %s\n", w->error().c_str());
      return 3;
    }
    std::fflush(stdout);
    _exit(0);
  }
  if (!w->close()) {
    std::fprintf(stderr, "mcap-sample: %s\n", w->error().c_str());
    return 3;
  }
  std::printf("%llu messages\n", static_cast<unsigned long long>(w->message_count()));
  return 0;
}
