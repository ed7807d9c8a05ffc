// libFuzzer target: arbitrary bytes on the bridge link through the line assembler and the
// controller (with a key, armed first), plus each chunk as a reply line to the ground-station
// parser. Checks: no crash/UB/overflow (ASan/UBSan), every reply is one complete bounded line,
// and a control line is applied (200) only if it is exactly what the ground-station codec builds
// for those values under the key (canonical and correctly signed).
#include <stddef.h>
#include <stdint.h>

#include <cstdlib>
#include <string>

#include "controller.h"
#include "imu_cache.h"
#include "line_assembler.h"
#include "request_parser.h"
#include "rgbd_control/client_codec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const uint8_t kKey[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  fw::Controller c(kKey);
  fw::LineAssembler a;
  fw::ImuCache imu;
  char reply[fw::kReplyBufferBytes];
  uint32_t t = 0;
  for (size_t i = 0; i < size; ++i) {
    if (data[i] == 0xFE) t += 37;  // let time pass now and then (stall / failsafe paths)
    fw::LineEvent ev = a.feed(data[i], t);
    size_t n = 0;
    if (ev == fw::LineEvent::kLine) {
      n = c.handle_line(a.line(), a.length(), t, imu, reply, sizeof(reply));
      const fw::ParsedRequest r = fw::parse_request(a.line(), a.length());
      if (std::atoi(reply) == 200 && r.kind == fw::RequestKind::kControl) {
        rgbd_control::Key key;
        for (size_t k = 0; k < key.size(); ++k) key[k] = kKey[k];
        rgbd_control::ControlCommand cmd;
        cmd.seq = r.seq;
        cmd.arm = r.arm == 1;
        cmd.roll_us = static_cast<uint16_t>(r.channel_us[0]);
        cmd.pitch_us = static_cast<uint16_t>(r.channel_us[1]);
        cmd.thr_us = static_cast<uint16_t>(r.channel_us[2]);
        cmd.yaw_us = static_cast<uint16_t>(r.channel_us[3]);
        const auto expected = rgbd_control::build_control_request(key, cmd);
        if (!expected || *expected != std::string(a.line(), a.length())) abort();
      }
    } else if (ev == fw::LineEvent::kTooLong) {
      n = c.reply_error(fw::Status::kTooLong, t, imu, reply, sizeof(reply));
    } else if (a.poll(t) == fw::LineEvent::kStalled) {
      n = c.reply_error(fw::Status::kStalled, t, imu, reply, sizeof(reply));
    }
    if (n > 0 && (n >= sizeof(reply) || reply[n - 1] != '\n')) abort();
    c.update(t);
  }
  (void)rgbd_control::parse_reply(std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
