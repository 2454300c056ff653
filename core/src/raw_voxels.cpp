#include "raw_voxels.h"

#include <zlib.h>
#include <cmath>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "mvtwin/core/error.h"

namespace mvtwin::raw {

int bytes_of(VoxelType t) {
  switch (t) {
    case VoxelType::kU8:
    case VoxelType::kI8:
      return 1;
    case VoxelType::kU16:
    case VoxelType::kI16:
      return 2;
    case VoxelType::kU32:
    case VoxelType::kI32:
    case VoxelType::kF32:
      return 4;
    case VoxelType::kF64:
      return 8;
  }
  return 1;
}

std::string read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(path.string() + ": no such file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(path.string() + ": cannot be opened for reading");
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) throw Error(path.string() + ": read error");
  return ss.str();
}

std::size_t max_inflated_size(std::size_t compressed) {
  constexpr std::size_t kRatio = 1032, kSlack = 1024;
  if (compressed > (std::numeric_limits<std::size_t>::max() - kSlack) / kRatio)
    return std::numeric_limits<std::size_t>::max();
  return kRatio * compressed + kSlack;
}

std::string inflate(const std::string& in, std::size_t expected, const std::string& what) {
  if (in.size() > std::numeric_limits<uInt>::max() || expected > std::numeric_limits<uInt>::max())
    throw Error(what + ": compressed blocks over 4 GB are not supported");
  if (expected > max_inflated_size(in.size()))
    throw Error(what + ": the header claims " + std::to_string(expected) + " bytes from " +
                std::to_string(in.size()) +
                " compressed bytes, more than zlib can encode (a corrupt header or a "
                "compression bomb)");
  std::string out(expected, '\0');
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) throw Error(what + ": zlib initialization failed");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(expected);
  const int rc = ::inflate(&z, Z_FINISH);
  const std::string msg = z.msg ? z.msg : "error";
  const std::size_t got = expected - z.avail_out;
  inflateEnd(&z);
  if (rc != Z_STREAM_END && rc != Z_BUF_ERROR)
    throw Error(what + ": corrupt compressed data (zlib: " + msg + ")");
  if (got != expected) {
    throw Error(what + ": compressed data too short (expected " + std::to_string(expected) +
                " bytes, got " + std::to_string(got) + ")");
  }
  return out;
}

std::string deflate(const char* data, std::size_t bytes, bool gzip) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, gzip ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error("zlib: deflate initialization failed");
  std::string out(deflateBound(&z, static_cast<uLong>(bytes)) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data));
  z.avail_in = static_cast<uInt>(bytes);
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = ::deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (rc != Z_STREAM_END) throw Error("zlib: deflate failed");
  return out;
}

namespace {

template <typename T>
T load(const char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap)
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

template <typename T>
void convert(const std::string& bytes, bool swap, std::size_t n, std::vector<float>* out) {
  for (std::size_t i = 0; i < n; ++i)
    (*out)[i] = static_cast<float>(load<T>(bytes.data() + i * sizeof(T), swap));
}

}  // namespace

std::vector<float> decode(const std::string& bytes, VoxelType t, bool big_endian, std::size_t n) {
  constexpr bool host_big = std::endian::native == std::endian::big;
  const bool swap = big_endian != host_big;
  std::vector<float> out(n);
  switch (t) {
    case VoxelType::kU8:
      convert<std::uint8_t>(bytes, false, n, &out);
      break;
    case VoxelType::kI8:
      convert<std::int8_t>(bytes, false, n, &out);
      break;
    case VoxelType::kU16:
      convert<std::uint16_t>(bytes, swap, n, &out);
      break;
    case VoxelType::kI16:
      convert<std::int16_t>(bytes, swap, n, &out);
      break;
    case VoxelType::kU32:
      convert<std::uint32_t>(bytes, swap, n, &out);
      break;
    case VoxelType::kI32:
      convert<std::int32_t>(bytes, swap, n, &out);
      break;
    case VoxelType::kF32:
      convert<float>(bytes, swap, n, &out);
      break;
    case VoxelType::kF64:
      convert<double>(bytes, swap, n, &out);
      break;
  }
  return out;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const std::size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
}

std::string format_number(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

std::vector<std::string> words(const std::string& s) {
  std::istringstream is(s);
  std::vector<std::string> w;
  for (std::string x; is >> x;) w.push_back(x);
  return w;
}

double number(const std::string& s, const std::string& what) {
  const std::size_t a = s.find_first_not_of(" \t\r\n");
  const std::size_t b = s.find_last_not_of(" \t\r\n");
  const std::string t = a == std::string::npos ? "" : s.substr(a, b - a + 1);
  try {
    std::size_t used = 0;
    const double v = std::stod(t, &used);
    if (used == t.size()) return v;
  } catch (const std::exception&) {
  }
  if (t == "nan" || t == "NaN") return std::numeric_limits<double>::quiet_NaN();
  throw Error(what + ": '" + t + "' is not a number");
}

long whole(double v, const std::string& what, long lo, long hi) {
  if (!(v >= static_cast<double>(lo) && v <= static_cast<double>(hi) && v == std::floor(v)))
    throw Error(what + ": " + format_number(v) + " is not a whole number from " +
                std::to_string(lo) + " to " + std::to_string(hi));
  return static_cast<long>(v);
}

long whole_number(const std::string& s, const std::string& what, long lo, long hi) {
  return whole(number(s, what), what, lo, hi);
}

}  // namespace mvtwin::raw
