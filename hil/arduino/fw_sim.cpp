// fw_sim: runs the real firmware .elf on simavr's ATmega328P @ 16 MHz and plays a scenario script.
//
// Usage: fw_sim --elf FILE [--eeprom FILE] [--bridge-byte-us US] [--interactive] < script > log
//   --elf FILE       firmware image (firmware/.pio/build/uno_wifi/program.elf)
//   --bridge-byte-us US  period of the bridge bytes fed to the firmware (default 16, simavr's own
//                    UART byte time at 1 Mbaud, which is also the shortest it accepts); e.g. 20 or
//                    40 to model a WiFi bridge that forwards bytes more slowly than the wire
//   --eeprom FILE    raw bytes loaded into EEPROM at address 0 before reset (the key record)
//   --eeprom-out FILE  write the whole EEPROM (1024 bytes) to FILE when the simulation ends, to
//                    start a later run from it (a reset / power cycle of the board)
//   --stack-paint ADDR  fill SRAM from ADDR (the image's __bss_end, e.g. 0x6a2) to RAMEND with 0xAA
//                    before reset and report at the end how much of it was never written
//                    ("stack_free N"): the stack's high-water mark under the scenario's load
//   --interactive    lock-step co-simulation: commands are applied as they are read, and
//                    "run T" advances the simulation to T, then prints "at T" and flushes, so a
//                    driver (e.g. a flight-controller model) can react to the pulses before it
//                    sends the next inputs. Inputs must not be timed before the current simulated
//                    time.
// Script (stdin), one command per line, times in simulated microseconds:
//   req  T TEXT   send TEXT + '\n' on the bridge UART at T, or as soon as the previous request's
//                 reply line has arrived (the bridge forwards one request at a time); a reply that
//                 arrives while the line is still going out (a 414) counts as its reply
//   raw  T HEX    send raw bytes on the bridge UART at T (no reply awaited)
//                 Bridge bytes go out one per --bridge-byte-us, and only while simavr's UART takes
//                 them: not before the firmware has enabled its receiver (simavr drops bytes sent
//                 to a disabled receiver; the real bridge chip is not forwarding requests within
//                 the ~1 ms the ATmega takes to boot either), and never into a full input FIFO
//                 (flow control: simavr's XOFF, lifted when the FIFO has drained).
//   mav  T HEX    send bytes to the MAVLink telemetry pin (PD2) as 57600-baud 8N1 serial from T,
//                 or right after the previous burst if that one is still on the wire (one UART)
//   run  T        (interactive only) simulate up to T, then print "at T"
//   end  T        stop the simulation at T
// Log (stdout), one event per line:
//   pulse CH RISE_US WIDTH_US    a completed pulse on RC channel CH (1..4)
//   sent  START_US END_US        a request line finished going out on the bridge UART
//   reply START_US END_US TEXT   a reply line from the firmware (first byte, newline)
//   stack_free N                 (with --stack-paint) bytes above ADDR never written
//   done  END_US                 simulation finished
// Time comes from simavr's cycle counter only; the harness never reads the wall clock.
#include <avr_eeprom.h>
#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_irq.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace {

constexpr uint32_t kCpuHz = 16000000;
constexpr double kCyclesPerUs = kCpuHz / 1e6;
/// Bridge link bytes are fed by default at simavr 1.6's own UART byte time at the firmware's
/// 1000000 baud, 16 us (it models a byte as 16 bit times, measured from the firmware's TX; real 8N1
/// is 10 bit times = 10 us): faster feeding would pile bytes up in simavr's input FIFO and overflow
/// it on long lines, so it is also the shortest period --bridge-byte-us accepts.
constexpr uint64_t kMinBridgeByteCycles = 256;
/// MAVLink telemetry: 57600 baud; a bit lasts 16e6 / 57600 = 277.78 cycles.
constexpr double kMavBitCycles = kCpuHz / 57600.0;
/// Played inputs are freed once this many have piled up (Feeder::drop_played): 4096 pin edges are
/// ~400 MAVLink bytes, a few ms of telemetry, so a compaction moves little and runs rarely.
constexpr size_t kCompactMinEntries = 4096;
/// ATmega328P SRAM ends at 0x8FF; the stack starts there and grows down.
constexpr long kRamEnd = 0x8FF;
/// Fill byte for the stack high-water measurement.
constexpr uint8_t kStackPaint = 0xAA;
/// RC outputs PB1..PB4 = channels 1..4.
constexpr int kPwmPins[4] = {1, 2, 3, 4};

struct Request {
  uint64_t at_cycle;
  std::string bytes;
  bool await_reply;
};

struct PinEdge {
  uint64_t cycle;
  int level;
};

struct Sim {
  avr_t* avr = nullptr;
  // PWM measurement
  uint64_t rise_cycle[4] = {0, 0, 0, 0};
  bool high[4] = {false, false, false, false};
  // Bridge RX (firmware -> harness)
  std::string reply;
  uint64_t reply_start = 0;
  bool awaiting_reply = false;
  // Bridge TX (harness -> firmware) flow control: simavr raises XOFF when its UART input FIFO is
  // full and lowers it once the FIFO has drained (and when the receiver is enabled).
  bool uart_xoff = false;
};

/// ATmega328P UCSR0B (data-space address) and its receiver-enable bit: bytes sent to a disabled
/// receiver are dropped by simavr, so the harness holds them until the firmware enables it.
constexpr uint16_t kUcsr0bAddr = 0xC1;
constexpr uint8_t kRxen0Bit = 4;

bool bridge_rx_ready(const Sim& sim) {
  return !sim.uart_xoff && (sim.avr->data[kUcsr0bAddr] & (1u << kRxen0Bit)) != 0;
}

double us(uint64_t cycle) { return static_cast<double>(cycle) / kCyclesPerUs; }

void on_pwm_pin(avr_irq_t* irq, uint32_t value, void* param) {
  Sim* sim = static_cast<Sim*>(param);
  const int ch = static_cast<int>(irq->irq);  // ioport irq index = pin number
  int idx = -1;
  for (int i = 0; i < 4; ++i) {
    if (kPwmPins[i] == ch) idx = i;
  }
  if (idx < 0) return;
  const uint64_t now = sim->avr->cycle;
  if (value && !sim->high[idx]) {
    sim->high[idx] = true;
    sim->rise_cycle[idx] = now;
  } else if (!value && sim->high[idx]) {
    sim->high[idx] = false;
    std::printf("pulse %d %.3f %.3f\n", idx + 1, us(sim->rise_cycle[idx]),
                us(now - sim->rise_cycle[idx]));
  }
}

void on_uart_xoff(avr_irq_t*, uint32_t value, void* param) {
  static_cast<Sim*>(param)->uart_xoff = value != 0;
}

void on_uart_out(avr_irq_t*, uint32_t value, void* param) {
  Sim* sim = static_cast<Sim*>(param);
  const char c = static_cast<char>(value & 0xFF);
  if (sim->reply.empty()) sim->reply_start = sim->avr->cycle;
  if (c == '\n') {
    std::printf("reply %.3f %.3f %s\n", us(sim->reply_start), us(sim->avr->cycle),
                sim->reply.c_str());
    sim->reply.clear();
    sim->awaiting_reply = false;  // also when the line is still going out (a 414 on a long line)
  } else if (sim->reply.size() < 4096) {
    sim->reply += c;
  }
}

std::string from_hex(const std::string& h) {
  std::string out;
  for (size_t i = 0; i + 1 < h.size(); i += 2)
    out += static_cast<char>(std::stoi(h.substr(i, 2), nullptr, 16));
  return out;
}

/// Appends the pin levels of 8N1 serial bytes starting at `start` (idle high between bytes).
void append_serial_edges(std::vector<PinEdge>* edges, uint64_t start, const std::string& bytes) {
  double t = static_cast<double>(start);
  for (unsigned char b : bytes) {
    int bits[10];
    bits[0] = 0;
    for (int i = 0; i < 8; ++i) bits[1 + i] = (b >> i) & 1;
    bits[9] = 1;
    for (int i = 0; i < 10; ++i) {
      edges->push_back({static_cast<uint64_t>(t + 0.5), bits[i]});
      t += kMavBitCycles;
    }
  }
}

int usage(const char* msg) {
  std::fprintf(stderr,
               "fw_sim: %s\nusage: fw_sim --elf FILE [--eeprom FILE] [--eeprom-out FILE] "
               "[--stack-paint ADDR] [--bridge-byte-us US] [--interactive] < script > log\n",
               msg);
  return 2;
}

/// Inputs waiting to be played into the simulated chip, and the playing state.
struct Feeder {
  std::deque<Request> requests;  // in script order
  std::vector<Request> raws;     // sorted by time
  size_t raw_idx = 0;
  std::vector<PinEdge> mav_edges;  // sorted by time
  size_t mav_idx = 0;
  uint64_t mav_free_cycle = 0;  // when the telemetry wire is idle again
  std::string tx;               // bytes being fed into the bridge UART
  size_t tx_pos = 0;
  uint64_t tx_next = 0;
  uint64_t tx_start = 0;
  bool tx_is_request = false;
  uint64_t byte_cycles = kMinBridgeByteCycles;  // bridge byte period (--bridge-byte-us)

  /// Frees the inputs already played (the prefix before raw_idx / mav_idx). Without this a soak's
  /// hour of MAVLink (~10 pin edges per byte, 16 bytes each) stayed in memory: 5.9 -> 367 MB in
  /// 30 minutes. Compacting only once the played prefix is at least kCompactMinEntries and half
  /// the vector keeps the cost amortised O(1) per entry, and what is kept is what is still due.
  void drop_played() {
    if (mav_idx >= kCompactMinEntries && mav_idx * 2 >= mav_edges.size()) {
      mav_edges.erase(mav_edges.begin(), mav_edges.begin() + static_cast<long>(mav_idx));
      mav_idx = 0;
    }
    if (raw_idx >= kCompactMinEntries && raw_idx * 2 >= raws.size()) {
      raws.erase(raws.begin(), raws.begin() + static_cast<long>(raw_idx));
      raw_idx = 0;
    }
  }
  void add_raw(const Request& r) {
    auto it = std::upper_bound(
        raws.begin() + static_cast<long>(raw_idx), raws.end(), r,
        [](const Request& a, const Request& b) { return a.at_cycle < b.at_cycle; });
    raws.insert(it, r);
  }
  void add_mav(uint64_t at, const std::string& bytes) {
    const uint64_t start = std::max(at, mav_free_cycle);
    mav_free_cycle =
        start + static_cast<uint64_t>(static_cast<double>(bytes.size()) * 10 * kMavBitCycles + 0.5);
    std::vector<PinEdge> e;
    append_serial_edges(&e, start, bytes);
    mav_edges.insert(mav_edges.end(), e.begin(), e.end());
    std::stable_sort(mav_edges.begin() + static_cast<long>(mav_idx), mav_edges.end(),
                     [](const PinEdge& a, const PinEdge& b) { return a.cycle < b.cycle; });
  }
};

/// Parses one script line into the feeder. Returns 0 ok, 1 for "run"/"end" (with *at set), -1 on
/// error.
int apply_line(const std::string& line, int line_no, Feeder* f, std::string* cmd_out,
               uint64_t* at_out) {
  std::istringstream in(line);
  std::string cmd;
  double t_us = -1;
  in >> cmd >> t_us;
  if (!in || t_us < 0) {
    std::fprintf(stderr, "fw_sim: script line %d: expected 'CMD T ...'\n", line_no);
    return -1;
  }
  const uint64_t at = static_cast<uint64_t>(t_us * kCyclesPerUs);
  std::string rest;
  std::getline(in, rest);
  if (!rest.empty() && rest[0] == ' ') rest.erase(0, 1);
  if (cmd == "req") {
    f->requests.push_back({at, rest + "\n", true});
  } else if (cmd == "raw") {
    f->add_raw({at, from_hex(rest), false});
  } else if (cmd == "mav") {
    f->add_mav(at, from_hex(rest));
  } else if (cmd == "run" || cmd == "end") {
    *cmd_out = cmd;
    *at_out = at;
    return 1;
  } else {
    std::fprintf(stderr, "fw_sim: script line %d: unknown command '%s'\n", line_no, cmd.c_str());
    return -1;
  }
  return 0;
}

/// Simulates until `end_cycle`, playing the feeder's inputs at their times. Returns the CPU state.
int run_until(Sim* sim, Feeder* f, avr_irq_t* uart_in, avr_irq_t* mav_pin, uint64_t end_cycle) {
  int state = cpu_Running;
  while (sim->avr->cycle < end_cycle && state != cpu_Done && state != cpu_Crashed) {
    state = avr_run(sim->avr);
    const uint64_t now = sim->avr->cycle;
    while (f->mav_idx < f->mav_edges.size() && now >= f->mav_edges[f->mav_idx].cycle) {
      avr_raise_irq(mav_pin, static_cast<uint32_t>(f->mav_edges[f->mav_idx].level));
      ++f->mav_idx;
    }
    f->drop_played();
    if (f->tx_pos < f->tx.size()) {
      if (now >= f->tx_next && bridge_rx_ready(*sim)) {
        // On schedule, bytes keep the exact byte time; the first byte and the first one after a
        // flow-control pause restart the schedule, so the rest of a line never goes out in a burst.
        if (f->tx_pos == 0) f->tx_start = now;
        if (f->tx_pos == 0 || now - f->tx_next > f->byte_cycles) f->tx_next = now;
        avr_raise_irq(uart_in, static_cast<uint8_t>(f->tx[f->tx_pos++]));
        f->tx_next += f->byte_cycles;
        if (f->tx_pos == f->tx.size() && f->tx_is_request) {
          std::printf("sent %.3f %.3f\n", us(f->tx_start), us(f->tx_next));
        }
      }
      continue;
    }
    if (f->raw_idx < f->raws.size() && now >= f->raws[f->raw_idx].at_cycle &&
        (f->requests.empty() || f->raws[f->raw_idx].at_cycle <= f->requests.front().at_cycle)) {
      f->tx = f->raws[f->raw_idx++].bytes;
      f->tx_is_request = false;
    } else if (!f->requests.empty() && !sim->awaiting_reply &&
               now >= f->requests.front().at_cycle) {
      f->tx = f->requests.front().bytes;
      f->requests.pop_front();
      f->tx_is_request = true;
      // Waiting for the reply from the start: it may arrive before the last byte has gone out (a
      // 414 on an over-long line), and must then not be waited for again after that byte.
      sim->awaiting_reply = true;
    } else {
      continue;
    }
    f->tx_pos = 0;
    f->tx_next = now;
    f->tx_start = now;
  }
  return state;
}

}  // namespace

int main(int argc, char** argv) {
  std::string elf_path;
  std::string eeprom_path;
  std::string eeprom_out_path;
  long stack_paint_addr = -1;
  double bridge_byte_us = static_cast<double>(kMinBridgeByteCycles) / kCyclesPerUs;
  bool interactive = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--elf" && i + 1 < argc) {
      elf_path = argv[++i];
    } else if (a == "--eeprom" && i + 1 < argc) {
      eeprom_path = argv[++i];
    } else if (a == "--eeprom-out" && i + 1 < argc) {
      eeprom_out_path = argv[++i];
    } else if (a == "--stack-paint" && i + 1 < argc) {
      stack_paint_addr = std::strtol(argv[++i], nullptr, 0);
      if (stack_paint_addr < 0x100 || stack_paint_addr > kRamEnd)
        return usage("--stack-paint: address outside SRAM");
    } else if (a == "--bridge-byte-us" && i + 1 < argc) {
      bridge_byte_us = std::strtod(argv[++i], nullptr);
      if (!(bridge_byte_us * kCyclesPerUs >= static_cast<double>(kMinBridgeByteCycles)) ||
          bridge_byte_us > 1e6)
        return usage("--bridge-byte-us: below simavr's 16 us UART byte time or not a number");
    } else if (a == "--interactive") {
      interactive = true;
    } else if (a == "-h" || a == "--help") {
      std::printf(
          "usage: fw_sim --elf FILE [--eeprom FILE] [--eeprom-out FILE] [--stack-paint ADDR] "
          "[--bridge-byte-us US] [--interactive] < script > log\n"
          "Runs the firmware image on simavr (ATmega328P, 16 MHz) and plays the script;\n"
          "see the header of hil/arduino/fw_sim.cpp for the script and log formats.\n");
      return 0;
    } else {
      return usage(("unknown argument " + a).c_str());
    }
  }
  if (elf_path.empty()) return usage("--elf is required");

  // Batch mode reads the whole script first; interactive mode reads it as it goes (below).
  Feeder feeder;
  feeder.byte_cycles = static_cast<uint64_t>(bridge_byte_us * kCyclesPerUs + 0.5);
  uint64_t end_cycle = 0;
  std::string line;
  int line_no = 0;
  if (!interactive) {
    while (std::getline(std::cin, line)) {
      ++line_no;
      if (line.empty() || line[0] == '#') continue;
      std::string cmd;
      uint64_t at = 0;
      const int rc = apply_line(line, line_no, &feeder, &cmd, &at);
      if (rc < 0) return 2;
      if (rc == 1 && cmd == "run") {
        std::fprintf(stderr, "fw_sim: script line %d: 'run' needs --interactive\n", line_no);
        return 2;
      }
      if (rc == 1) end_cycle = at;
    }
    if (end_cycle == 0) {
      std::fprintf(stderr, "fw_sim: script has no 'end T' line\n");
      return 2;
    }
  }

  // Firmware.
  elf_firmware_t fw;
  std::memset(&fw, 0, sizeof(fw));
  if (elf_read_firmware(elf_path.c_str(), &fw) != 0) {
    std::fprintf(stderr, "fw_sim: cannot read ELF %s\n", elf_path.c_str());
    return 1;
  }
  Sim sim;
  sim.avr = avr_make_mcu_by_name("atmega328p");
  if (sim.avr == nullptr) {
    std::fprintf(stderr, "fw_sim: simavr has no atmega328p\n");
    return 1;
  }
  avr_init(sim.avr);
  sim.avr->frequency = kCpuHz;
  avr_load_firmware(sim.avr, &fw);
  sim.avr->log = 0;
  if (stack_paint_addr >= 0) {
    std::memset(sim.avr->data + stack_paint_addr, kStackPaint,
                static_cast<size_t>(kRamEnd + 1 - stack_paint_addr));
  }
  if (!eeprom_path.empty()) {
    std::ifstream f(eeprom_path, std::ios::binary);
    if (!f) {
      std::fprintf(stderr, "fw_sim: cannot read EEPROM file %s\n", eeprom_path.c_str());
      return 1;
    }
    std::vector<uint8_t> ee((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    avr_eeprom_desc_t d;
    d.ee = ee.data();
    d.offset = 0;
    d.size = static_cast<uint32_t>(ee.size());
    avr_ioctl(sim.avr, AVR_IOCTL_EEPROM_SET, &d);
  }
  uint32_t flags = 0;
  avr_ioctl(sim.avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
  flags &= ~static_cast<uint32_t>(AVR_UART_FLAG_STDIO);
  avr_ioctl(sim.avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  for (int pin : kPwmPins) {
    avr_irq_register_notify(avr_io_getirq(sim.avr, AVR_IOCTL_IOPORT_GETIRQ('B'), pin), on_pwm_pin,
                            &sim);
  }
  avr_irq_register_notify(avr_io_getirq(sim.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                          on_uart_out, &sim);
  avr_irq_register_notify(avr_io_getirq(sim.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                          on_uart_xoff, &sim);
  avr_irq_t* uart_in = avr_io_getirq(sim.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
  avr_irq_t* mav_pin = avr_io_getirq(sim.avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 2);
  avr_raise_irq(mav_pin, 1);  // idle line high

  // Run.
  int state = cpu_Running;
  if (!interactive) {
    state = run_until(&sim, &feeder, uart_in, mav_pin, end_cycle);
  } else {
    while (std::getline(std::cin, line)) {
      ++line_no;
      if (line.empty() || line[0] == '#') continue;
      std::string cmd;
      uint64_t at = 0;
      const int rc = apply_line(line, line_no, &feeder, &cmd, &at);
      if (rc < 0) return 2;
      if (rc == 0) continue;
      state = run_until(&sim, &feeder, uart_in, mav_pin, at);
      if (cmd == "end" || state == cpu_Done || state == cpu_Crashed) break;
      std::printf("at %.3f\n", us(sim.avr->cycle));
      std::fflush(stdout);
    }
  }
  if (!eeprom_out_path.empty()) {
    std::vector<uint8_t> ee(1024, 0xFF);  // ATmega328P: 1 KB EEPROM
    avr_eeprom_desc_t d;
    d.ee = ee.data();
    d.offset = 0;
    d.size = static_cast<uint32_t>(ee.size());
    // simavr 1.6 copies into d.ee but does not return 0 for this ioctl: the result is not checked
    // (the replay-after-reset test proves the copy).
    avr_ioctl(sim.avr, AVR_IOCTL_EEPROM_GET, &d);
    std::ofstream out(eeprom_out_path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(ee.data()), static_cast<std::streamsize>(ee.size()));
    if (!out) {
      std::fprintf(stderr, "fw_sim: cannot write %s\n", eeprom_out_path.c_str());
      return 1;
    }
  }
  if (stack_paint_addr >= 0) {
    long n = 0;
    while (stack_paint_addr + n <= kRamEnd && sim.avr->data[stack_paint_addr + n] == kStackPaint)
      ++n;
    std::printf("stack_free %ld\n", n);
  }
  std::printf("done %.3f\n", us(sim.avr->cycle));
  if (state == cpu_Crashed) {
    std::fprintf(stderr, "fw_sim: firmware crashed at %.3f us\n", us(sim.avr->cycle));
    return 3;
  }
  std::fflush(stdout);
  // uart_pty_stop() hangs in simavr 1.6 and avr_terminate is not needed: just exit.
  std::_Exit(0);
}
