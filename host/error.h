// The one error type: any failure that should end the program with a
// one-line message.
#pragma once

#include <stdexcept>
#include <string>

namespace ht {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// Messages are one line of printable text: control characters (a newline
// in a library's message, in a file name or a JSON key) are shown escaped.
std::string oneLine(const std::string& s);

}  // namespace ht
