// The failure path of the options structs' is_valid(std::string* error): one call stores the
// message, when the caller asked for it, and yields the false that is_valid returns.
#pragma once

#include <string>
#include <utility>

namespace rgbdquad::quadcontrol {

/// Stores `message` in *error unless error is null; always false.
inline bool reject(std::string* error, std::string message) {
  if (error) *error = std::move(message);
  return false;
}

}  // namespace rgbdquad::quadcontrol
