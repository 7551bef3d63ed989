// Output files that are replaced whole or not at all.
//
// A regular (or new) target is written to a temporary file in its own
// directory, flushed, synced and closed with every error checked, then
// renamed over the target: a failure, a crash or a signal leaves the previous
// file as it was. Targets that exist and are not regular files (/dev/null,
// /dev/full, a FIFO) cannot be renamed over and are written directly, still
// with every write and the close checked.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace ht {

class OutputFile {
 public:
  // Creates the temporary (so an unwritable directory fails here, before any
  // work is done). Throws ht::Error "cannot write <target>: <reason>".
  explicit OutputFile(const std::string& target);
  ~OutputFile();  // removes the temporary unless committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  const std::string& target() const { return target_; }
  // Where the writer puts the bytes: the temporary, or the target itself.
  const std::string& path() const { return path_; }
  bool direct() const { return direct_; }

  // Syncs the temporary and renames it over the target. Throws ht::Error.
  void commit();
  // Removes the temporary now (after a failed write).
  void discard();

 private:
  std::string target_, renameTo_, path_;
  bool direct_ = false;
  bool pending_ = false;
  int slot_ = -1;
};

// Writes `size` bytes to the file with every write and the close checked.
void writeBytes(OutputFile& file, const void* data, size_t size);
// The same through a temporary: the whole job for a small file.
void writeFileAtomically(const std::string& target, const std::string& bytes);

// SIGINT, SIGTERM, SIGHUP: remove every temporary still in progress, then
// die of the same signal. Idempotent.
void removeOutputsOnSignals();

// Refuses, before any work, outputs that cannot be written: a missing or
// unwritable directory, a directory in place of the file, an unwritable
// file, and two outputs naming the same file. Each entry: option name, path.
void checkOutputPaths(const std::vector<std::pair<std::string, std::string>>& outputs);

}  // namespace ht
