#include "output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>

#include <fmt/format.h>

#include "error.h"

namespace ht {

namespace fs = std::filesystem;

namespace {

// Temporaries in progress, for the signal handler: fixed storage, read with
// nothing but atomic loads and unlink(), which are async-signal-safe.
constexpr int kSlots = 64;
constexpr size_t kMaxPath = 4096;
enum : int { kFree = 0, kFilling = 1, kActive = 2 };
std::atomic<int> gSlotState[kSlots];
char gSlotPath[kSlots][kMaxPath];

int claimSlot(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (gSlotState[i].compare_exchange_strong(expected, kFilling)) {
      std::memcpy(gSlotPath[i], path.c_str(), path.size() + 1);
      gSlotState[i].store(kActive);
      return i;
    }
  }
  return -1;  // more outputs at once than slots: still written safely, only not cleaned up on a signal
}

void releaseSlot(int& slot) {
  if (slot >= 0) gSlotState[slot].store(kFree);
  slot = -1;
}

extern "C" void removeTemporariesAndDie(int sig) {
  const int saved = errno;
  for (int i = 0; i < kSlots; ++i)
    if (gSlotState[i].load() == kActive) unlink(gSlotPath[i]);
  errno = saved;
  // SA_RESETHAND restored the default action; the signal is blocked until
  // this handler returns, then it ends the process as it would have.
  raise(sig);
}

Error writeError(const std::string& target, int err) {
  return Error(oneLine(fmt::format("cannot write {}: {}", target, err != 0 ? std::strerror(err) : "write failed")));
}

std::string temporaryName(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  std::string name = target.filename().string().substr(0, 200);
  return (target.parent_path() / fmt::format(".{}.tmp.{}.{}", name, getpid(), counter++)).string();
}

}  // namespace

OutputFile::OutputFile(const std::string& target) : target_(target) {
  std::error_code ec;
  const fs::file_status st = fs::status(target, ec);
  if (fs::is_directory(st)) throw writeError(target, EISDIR);
  if (fs::exists(st) && !fs::is_regular_file(st)) {
    direct_ = true;  // a device or a FIFO: there is nothing to rename over
    path_ = target;
    return;
  }
  // A link to a regular file: replace the file it names and keep the link.
  fs::path real = fs::exists(st) ? fs::canonical(target, ec) : fs::path(target);
  if (ec) real = target;
  if (real.parent_path().empty()) real = fs::path(".") / real;
  renameTo_ = real.string();
  path_ = temporaryName(real);
  slot_ = claimSlot(path_);
  const int fd = open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int e = errno;
    releaseSlot(slot_);
    throw writeError(target, e);
  }
  pending_ = true;
  // The new file keeps the permissions of the one it replaces.
  struct stat old;
  if (stat(renameTo_.c_str(), &old) == 0 && S_ISREG(old.st_mode)) fchmod(fd, old.st_mode & 07777);
  close(fd);
}

OutputFile::~OutputFile() { discard(); }

void OutputFile::discard() {
  if (pending_) unlink(path_.c_str());
  pending_ = false;
  releaseSlot(slot_);
}

void OutputFile::commit() {
  if (direct_) return;
  if (!pending_) throw Error(oneLine("cannot write " + target_ + ": nothing was written"));
  // Tests stop here, with the whole file written under its temporary name,
  // to send a signal at a known point.
  if (const char* hold = std::getenv("HTRENDER_TEST_HOLD_BEFORE_RENAME"); hold && *hold) {
    std::fprintf(stderr, "holding %s\n", path_.c_str());
    for (int s = std::atoi(hold); s > 0;) s = int(sleep(unsigned(s)));
  }
  const int fd = open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || fsync(fd) != 0) {
    const int e = errno;
    if (fd >= 0) close(fd);
    discard();
    throw writeError(target_, e);
  }
  close(fd);
  if (rename(path_.c_str(), renameTo_.c_str()) != 0) {
    const int e = errno;
    discard();
    throw writeError(target_, e);
  }
  pending_ = false;
  releaseSlot(slot_);
}

void writeBytes(OutputFile& file, const void* data, size_t size) {
  const int fd = open(file.path().c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (fd < 0) throw writeError(file.target(), errno);
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : ENOSPC;
      close(fd);
      file.discard();
      throw writeError(file.target(), e);
    }
    p += n;
    size -= size_t(n);
  }
  if (close(fd) != 0) {
    const int e = errno;
    file.discard();
    throw writeError(file.target(), e);
  }
}

void writeFileAtomically(const std::string& target, const std::string& bytes) {
  OutputFile file(target);
  writeBytes(file, bytes.data(), bytes.size());
  file.commit();
}

void removeOutputsOnSignals() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction sa;
    std::memset(&sa, 0, sizeof sa);
    sa.sa_handler = removeTemporariesAndDie;
    sa.sa_flags = SA_RESETHAND;
    sigemptyset(&sa.sa_mask);
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction old;
      // A signal the caller chose to ignore (nohup) stays ignored.
      if (sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
      sigaction(sig, &sa, nullptr);
    }
  });
}

void checkOutputPaths(const std::vector<std::pair<std::string, std::string>>& outputs) {
  std::vector<fs::path> seen;
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [option, path] = outputs[i];
    const fs::path p(path);
    const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
    std::error_code ec;
    if (!fs::is_directory(dir, ec))
      throw Error(oneLine(fmt::format("{}: output directory {}", dir.string(),
                                      fs::exists(dir, ec) ? "is not a directory" : "does not exist")));
    if (access(dir.c_str(), W_OK) != 0)
      throw Error(oneLine(fmt::format("{}: output directory is not writable", dir.string())));
    if (fs::is_directory(p, ec)) throw writeError(path, EISDIR);
    if (fs::exists(p, ec) && access(p.c_str(), W_OK) != 0)
      throw Error(oneLine(fmt::format("{}: output file is not writable", path)));
    fs::path key = fs::weakly_canonical(p, ec);
    if (ec) key = fs::absolute(p).lexically_normal();
    for (size_t j = 0; j < seen.size(); ++j) {
      std::error_code eq;
      if (seen[j] == key || fs::equivalent(seen[j], key, eq))
        throw Error(oneLine(fmt::format("{} and {} name the same file {}: each output needs its own",
                                        outputs[j].first, option, path)));
    }
    seen.push_back(key);
  }
}

}  // namespace ht
