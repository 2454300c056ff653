#pragma once
#include <cstdint>
#include <cstdio>
#include <string>

namespace mvtwin {

/// A short key (FNV-1a, 8 hex digits) naming cached files by what made them, so that a changed
/// setting never reuses a file made otherwise.
inline std::string cache_key(const std::string& description) {
  std::uint64_t key = 1469598103934665603ull;  // FNV-1a
  for (char c : description) key = (key ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(key));
  return std::string(hex, 8);
}

}  // namespace mvtwin
