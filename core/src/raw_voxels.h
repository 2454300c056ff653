#pragma once
// Raw voxel bytes shared by the NRRD and MetaImage readers and writers: file bytes, zlib/gzip,
// voxel types and byte order.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace mvtwin::raw {

enum class VoxelType { kU8, kI8, kU16, kI16, kU32, kI32, kF32, kF64 };

int bytes_of(VoxelType t);

/// The whole file; throws mvtwin::Error naming it when missing or unreadable.
std::string read_file_bytes(const std::filesystem::path& path);

/// The most `compressed` bytes of zlib or gzip data can inflate to: deflate encodes at most 1032
/// bytes per input byte (zlib's technical details), plus a header's worth. A header that claims
/// more data than this is corrupt or a compression bomb, and is refused before allocating.
std::size_t max_inflated_size(std::size_t compressed);

/// Inflates zlib or gzip data (detected from its header) that must give exactly `expected`
/// bytes; throws mvtwin::Error naming `what` for corrupt or short data, or when `expected` is
/// more than the data can inflate to (nothing is allocated then).
std::string inflate(const std::string& compressed, std::size_t expected, const std::string& what);

/// Deflates to gzip (`gzip` true: NRRD's "gzip" encoding) or zlib (MetaImage) format.
std::string deflate(const char* data, std::size_t bytes, bool gzip);

/// `count` voxels of type `t` from `bytes` (at least count * bytes_of(t) of them), converted to
/// float; `big_endian` for the file's byte order.
std::vector<float> decode(const std::string& bytes, VoxelType t, bool big_endian,
                          std::size_t count);

/// Lower-case copy (ASCII).
std::string lower(std::string s);
/// `s` without leading and trailing blanks (spaces, tabs, carriage returns).
std::string trim(const std::string& s);
/// Shortest text that reads back as the same double (%.17g).
std::string format_number(double v);

/// Splits on whitespace.
std::vector<std::string> words(const std::string& s);

/// Parses a floating-point number that must fill `s` (after trimming); throws mvtwin::Error
/// with `what` in the message otherwise.
double number(const std::string& s, const std::string& what);
/// A whole number read from a file (as a double): throws mvtwin::Error naming `what` unless it
/// is finite, integral and in [lo, hi] (a cast of 1e300 to an integer is undefined behaviour;
/// the fuzzers found three).
long whole(double v, const std::string& what, long lo, long hi);
/// number() that must also be whole and in [lo, hi].
long whole_number(const std::string& s, const std::string& what, long lo, long hi);

}  // namespace mvtwin::raw
