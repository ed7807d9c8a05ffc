// quad-control's log lines on stderr. Several threads log (frame, SLAM link, firmware link,
// dashboard, the stream receiver's), and std::cerr is unbuffered: a line inserted in pieces goes
// out as several write(2)s, between which another thread's line can land (a test reading the
// dashboard's port once saw that). Each line is therefore assembled first and written in one piece.
#pragma once

#include <string_view>

namespace rgbdquad::quadcontrol {

/// Writes "quad-control: <line>\n" to stderr in one write.
void log_line(std::string_view line);

}  // namespace rgbdquad::quadcontrol
