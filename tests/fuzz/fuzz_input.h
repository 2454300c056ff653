#pragma once
// What every fuzz harness shares (issue 15; docs/fuzzing.md). The readers take paths, as the
// commands do, so the fuzzer's bytes are written to a file with the reader's file ending, and
// the reader the command calls is called on it. mvtwin::Error is the readers' answer to bad
// input; anything else escaping (another exception, a crash, a sanitizer report, a hang, a
// large allocation) is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "mvtwin/core/error.h"

namespace mvtwin::fuzz {

/// A directory of this process's own (MVTWIN_FUZZ_TMP or the system's temporary directory).
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const char* base = std::getenv("MVTWIN_FUZZ_TMP");
    std::filesystem::path d =
        base && *base ? std::filesystem::path(base) : std::filesystem::temp_directory_path();
    d /= "mvtwin-fuzz-" + std::to_string(::getpid());
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

/// Writes [data, data + size) to the scratch directory as "input<ending>" and calls
/// read(path), swallowing mvtwin::Error only.
template <typename Read>
int read_bytes(const std::uint8_t* data, std::size_t size, const std::string& ending, Read read) {
  const std::filesystem::path path = scratch_dir() / ("input" + ending);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    read(path);
  } catch (const mvtwin::Error&) {
  }
  return 0;
}

/// For harnesses that read several formats: the first byte picks the ending (modulo the
/// count), the rest is the file.
template <std::size_t N, typename Read>
int read_bytes_as_one_of(const std::uint8_t* data, std::size_t size,
                         const char* const (&endings)[N], Read read) {
  if (size == 0) return 0;
  return read_bytes(data + 1, size - 1, endings[data[0] % N], read);
}

}  // namespace mvtwin::fuzz
