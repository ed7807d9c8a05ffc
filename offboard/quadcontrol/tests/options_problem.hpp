// Test support: the message an options struct's is_valid(std::string* error) gives, so a table of
// cases can assert on the reason as well as on the verdict.
#pragma once

#include <string>

namespace rgbdquad::quadcontrol::testing {

/// Empty when `options` are valid, else the reason is_valid() gave.
template <typename Options>
std::string problem(const Options& options) {
  std::string error;
  return options.is_valid(&error) ? std::string() : error;
}

}  // namespace rgbdquad::quadcontrol::testing
