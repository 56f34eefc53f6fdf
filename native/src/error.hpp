// The library's one error type: a status code of rocks.h and a one-line message. Every C function catches it
// (and std::bad_alloc, and anything else) and returns the code, keeping the message for rocks_last_error.
#pragma once

#include <stdexcept>
#include <string>

#include "rocks.h"

namespace rocks {

class Error : public std::runtime_error {
 public:
  Error(int status, const std::string& message) : std::runtime_error(message), status(status) {}
  int status;
};

}  // namespace rocks
