#include "mvtwin/core/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>

#include <atomic>
#include <mutex>
#include <set>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin {

namespace {

// A process killed while writing (SIGKILL, power loss) leaves its temporary file behind
// (".NAME.tmp-PID-N"): the first write of a process into a directory removes the temporaries
// there whose process PID no longer exists, once per directory (a study writing thousands of
// records into one folder scans it once, not once per record). A live writer's temporary is
// never touched.
void remove_stale_temporaries(const std::filesystem::path& dir) {
  static std::mutex mutex;
  static std::set<std::string> cleaned;
  std::error_code ec;
  const std::string key = std::filesystem::absolute(dir, ec).lexically_normal().string();
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!cleaned.insert(key).second) return;
  }
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string entry = it->path().filename().string();
    const size_t mark = entry.rfind(".tmp-");
    if (entry.empty() || entry[0] != '.' || mark == std::string::npos || mark == 0) continue;
    const std::string rest = entry.substr(mark + 5);
    const size_t dash = rest.find('-');
    if (dash == 0 || dash == std::string::npos) continue;
    long pid = 0;
    try {
      size_t used = 0;
      pid = std::stol(rest.substr(0, dash), &used);
      if (used != dash) continue;
    } catch (const std::exception&) {
      continue;
    }
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code rm;
      std::filesystem::remove(it->path(), rm);
    }
  }
}

}  // namespace

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path dir =
      path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw Error(path.string() + ": cannot write, directory " + dir.string() + " does not exist");
  }
  remove_stale_temporaries(dir);
  const std::filesystem::path tmp =
      dir / ("." + path.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
             std::to_string(counter++));
  try {
    write(tmp);
    // Flush the data to disk before the rename makes it visible.
    const int fd = ::open(tmp.c_str(), O_RDONLY);
    if (fd >= 0) {
      ::fsync(fd);
      ::close(fd);
    }
    std::filesystem::rename(tmp, path, ec);
    if (ec)
      throw Error(path.string() + ": cannot move the finished file into place: " + ec.message());
  } catch (...) {
    std::filesystem::remove(tmp, ec);
    throw;
  }
}

void create_output_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create directory: " + ec.message());
}

}  // namespace mvtwin
