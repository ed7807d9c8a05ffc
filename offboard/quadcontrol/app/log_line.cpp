// quad-control's log lines: see log_line.hpp.
#include "app/log_line.hpp"

#include <iostream>
#include <string>

namespace rgbdquad::quadcontrol {

void log_line(std::string_view line) {
  std::string whole = "quad-control: ";
  whole.append(line);
  whole.push_back('\n');
  std::cerr.write(whole.data(), static_cast<std::streamsize>(whole.size()));
  std::cerr.flush();
}

}  // namespace rgbdquad::quadcontrol
