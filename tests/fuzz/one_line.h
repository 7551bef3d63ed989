// What a fuzz target asks of an error message: one line of printable text.
#pragma once

#include <cstdlib>

namespace ht::fuzz {

// Aborts, a finding, where `message` is empty or holds a control character.
inline void requireOneLine(const char* message) {
  if (*message == '\0') std::abort();
  for (; *message != '\0'; ++message)
    if ((unsigned char)*message < 0x20 || *message == 0x7f) std::abort();
}

}  // namespace ht::fuzz
