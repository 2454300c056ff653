#pragma once
#include <filesystem>
#include <functional>

namespace mvtwin {

/// Writes a file so that a crash or an error never leaves it half-written: `write` is given a
/// temporary path in the same directory; when it returns, the temporary is flushed to disk and
/// renamed over `path` (atomic on POSIX). If `write` throws, the temporary is removed, the
/// exception propagates and an existing file at `path` is untouched. A process killed while
/// writing leaves its temporary behind; a process's first write into a directory removes the
/// temporaries there of processes that no longer exist.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& tmp)>& write);

/// Creates an output directory (and its parents) if needed; throws mvtwin::Error naming it.
void create_output_directory(const std::filesystem::path& dir);

}  // namespace mvtwin
