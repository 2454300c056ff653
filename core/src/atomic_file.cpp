#include "mvtwin/core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin {

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path dir =
      path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw Error(path.string() + ": cannot write, directory " + dir.string() + " does not exist");
  }
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
