// MetaImage (.mha/.mhd) reading and writing, as ITK and 3D Slicer use it: physical space LPS,
// row i of TransformMatrix the direction of axis i.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "raw_voxels.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;
using raw::VoxelType;

const Eigen::Vector3d kLpsToRas(-1, -1, 1);

using raw::lower;
using raw::trim;

VoxelType met_type(const std::string& t, const std::string& what) {
  const std::string u = trim(t);
  if (u == "MET_UCHAR") return VoxelType::kU8;
  if (u == "MET_CHAR") return VoxelType::kI8;
  if (u == "MET_USHORT") return VoxelType::kU16;
  if (u == "MET_SHORT") return VoxelType::kI16;
  if (u == "MET_UINT") return VoxelType::kU32;
  if (u == "MET_INT") return VoxelType::kI32;
  if (u == "MET_FLOAT") return VoxelType::kF32;
  if (u == "MET_DOUBLE") return VoxelType::kF64;
  throw Error(what + ": unsupported MetaImage ElementType '" + u + "'");
}

std::vector<double> numbers(const std::string& s, std::size_t n, const std::string& what) {
  const std::vector<std::string> w = raw::words(s);
  if (w.size() != n)
    throw Error(what + ": expected " + std::to_string(n) + " values, found " +
                std::to_string(w.size()));
  std::vector<double> v;
  for (const auto& x : w) v.push_back(raw::number(x, what));
  return v;
}

bool truth(const std::string& s) {
  const std::string t = lower(trim(s));
  return t == "true" || t == "1";
}

}  // namespace

std::vector<ImageVolume> read_metaimage_series(const fs::path& path) {
  const std::string what = path.string();
  const std::string bytes = raw::read_file_bytes(path);
  std::map<std::string, std::string> field;  // lower-case keys
  std::size_t pos = 0;
  bool has_data_line = false;
  while (pos < bytes.size()) {
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    const std::string line = trim(bytes.substr(pos, end - pos));
    pos = std::min(end + 1, bytes.size());
    if (line.empty()) continue;
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos)
      throw Error(what + ": malformed MetaImage header line '" + line.substr(0, 60) + "'");
    const std::string key = lower(trim(line.substr(0, eq)));
    field[key] = trim(line.substr(eq + 1));
    if (key == "elementdatafile") {
      has_data_line = true;
      break;  // the last header field: LOCAL data starts on the next byte
    }
    if (field.size() > 200) break;
  }
  if (!field.count("ndims") || !has_data_line)
    throw Error(what + ": not a MetaImage header (needs NDims ... ElementDataFile)");
  if (field.count("objecttype") && lower(field["objecttype"]) != "image")
    throw Error(what + ": MetaImage ObjectType '" + field["objecttype"] + "' is not Image");
  const int nd = static_cast<int>(raw::whole_number(field["ndims"], what + " (NDims)", 0, 64));
  if (nd != 3 && nd != 4)
    throw Error(what + ": expected a 3D or 3D+t image, found NDims = " + std::to_string(nd));
  if (field.count("elementnumberofchannels") &&
      raw::number(field["elementnumberofchannels"], what) != 1)
    throw Error(what + ": images with several channels per voxel are not supported");
  if (!field.count("dimsize")) throw Error(what + ": MetaImage header lacks DimSize");
  if (!field.count("elementtype")) throw Error(what + ": MetaImage header lacks ElementType");
  const std::vector<double> ds = numbers(field["dimsize"], nd, what + " (DimSize)");
  for (double d : ds)
    if (!(d >= 1 && d < 1e6 && d == std::floor(d)))
      throw Error(what + ": bad DimSize entry " + raw::format_number(d));
  const VoxelType type = met_type(field["elementtype"], what);
  std::vector<double> sp(nd, 1.0), off(nd, 0.0), tm;
  for (const char* k : {"elementspacing", "elementsize"})
    if (field.count(k)) {
      sp = numbers(field[k], nd, what + " (" + k + ")");
      break;
    }
  for (const char* k : {"offset", "origin", "position"})
    if (field.count(k)) {
      off = numbers(field[k], nd, what + " (" + k + ")");
      break;
    }
  for (const char* k : {"transformmatrix", "rotation", "orientation"})
    if (field.count(k)) {
      tm = numbers(field[k], static_cast<std::size_t>(nd * nd), what + " (" + k + ")");
      break;
    }
  ImageVolume geom;
  for (int a = 0; a < 3; ++a) {
    geom.size[a] = static_cast<int>(ds[a]);
    if (!(sp[a] > 0) || !std::isfinite(sp[a]))
      throw Error(what + ": ElementSpacing along axis " + std::to_string(a) + " is not positive");
    geom.spacing[a] = sp[a];
    Eigen::Vector3d d = Eigen::Vector3d::Unit(a);
    if (!tm.empty()) d = Eigen::Vector3d(tm[a * nd], tm[a * nd + 1], tm[a * nd + 2]);
    if (!(d.norm() > 0) || !d.allFinite())
      throw Error(what + ": TransformMatrix row " + std::to_string(a) + " is zero or not finite");
    geom.direction.col(a) = kLpsToRas.cwiseProduct(d.normalized());
  }
  geom.origin = kLpsToRas.cwiseProduct(Eigen::Vector3d(off[0], off[1], off[2]));
  if (!geom.origin.allFinite()) throw Error(what + ": Offset is not finite");
  const long nt = nd == 4 ? static_cast<long>(ds[3]) : 1;
  const std::size_t nvox = geom.num_voxels(), total = nvox * static_cast<std::size_t>(nt);
  const std::size_t need = total * static_cast<std::size_t>(raw::bytes_of(type));

  std::string data;
  const std::string df = field["elementdatafile"];
  if (lower(df) == "local") {
    data = bytes.substr(pos);
  } else {
    if (lower(df).rfind("list", 0) == 0 || df.find('%') != std::string::npos ||
        raw::words(df).size() > 1)
      throw Error(what + ": multi-file MetaImage data ('" + df + "') is not supported");
    fs::path dp = df;
    if (dp.is_relative()) dp = path.parent_path() / dp;
    data = raw::read_file_bytes(dp);
    if (field.count("headersize")) {
      const long hs = raw::whole_number(field["headersize"], what + " (HeaderSize)", -1, 1L << 50);
      if (hs == -1 && data.size() >= need)
        data.erase(0, data.size() - need);
      else if (hs > 0 && static_cast<std::size_t>(hs) <= data.size())
        data.erase(0, static_cast<std::size_t>(hs));
      else if (hs != 0 && hs != -1)
        throw Error(what + ": HeaderSize goes past the data");
    }
  }
  if (field.count("compresseddata") && truth(field["compresseddata"])) {
    data = raw::inflate(data, need, what);
  } else if (data.size() < need) {
    throw Error(what + ": truncated voxel data (expected " + std::to_string(need) +
                " bytes, found " + std::to_string(data.size()) + ")");
  }
  bool big = false;
  for (const char* k : {"elementbyteordermsb", "binarydatabyteordermsb"})
    if (field.count(k)) big = truth(field[k]);
  const std::vector<float> values = raw::decode(data, type, big, total);
  std::vector<ImageVolume> out;
  for (long f = 0; f < nt; ++f) {
    ImageVolume im = geom;
    im.time_s = nd == 4 ? off[3] + f * sp[3] : 0.0;
    im.data.assign(values.begin() + static_cast<long>(nvox) * f,
                   values.begin() + static_cast<long>(nvox) * (f + 1));
    out.push_back(std::move(im));
  }
  return out;
}

void write_metaimage_series(const fs::path& path, const std::vector<ImageVolume>& s) {
  const std::string what = path.string();
  const bool series = s.size() > 1;
  const int nd = series ? 4 : 3;
  double dt = 1.0;
  if (series) {
    dt = s[1].time_s - s[0].time_s;
    for (std::size_t f = 1; f < s.size(); ++f)
      if (!(dt > 0) || std::abs(s[f].time_s - s[0].time_s - f * dt) > 1e-6 * std::max(1.0, dt * f))
        throw Error(what + ": MetaImage stores evenly spaced frames only; write .nrrd instead");
  }
  const ImageVolume& g = s.front();
  std::ostringstream h;
  h << "ObjectType = Image\nNDims = " << nd
    << "\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
    << "CompressedData = True\n";
  h << "TransformMatrix =";
  for (int a = 0; a < nd; ++a) {
    for (int c = 0; c < nd; ++c) {
      double v = a == c ? 1.0 : 0.0;
      if (a < 3 && c < 3) v = kLpsToRas[c] * g.direction(c, a);
      h << " " << raw::format_number(v);
    }
  }
  const Eigen::Vector3d o = kLpsToRas.cwiseProduct(g.origin);
  h << "\nOffset = " << raw::format_number(o[0]) << " " << raw::format_number(o[1]) << " "
    << raw::format_number(o[2]);
  if (series) h << " " << raw::format_number(s[0].time_s);
  h << "\nElementSpacing = " << raw::format_number(g.spacing[0]) << " "
    << raw::format_number(g.spacing[1]) << " " << raw::format_number(g.spacing[2]);
  if (series) h << " " << raw::format_number(dt);
  h << "\nDimSize = " << g.size[0] << " " << g.size[1] << " " << g.size[2];
  if (series) h << " " << s.size();
  std::vector<float> values;
  values.reserve(g.num_voxels() * s.size());
  for (const auto& im : s) values.insert(values.end(), im.data.begin(), im.data.end());
  const std::string z = raw::deflate(reinterpret_cast<const char*>(values.data()),
                                     values.size() * sizeof(float), false);
  h << "\nCompressedDataSize = " << z.size() << "\nElementType = MET_FLOAT\n";
  const bool local = lower(path.extension().string()) == ".mha";
  const fs::path data_path = fs::path(path).replace_extension(".zraw");
  h << "ElementDataFile = " << (local ? std::string("LOCAL") : data_path.filename().string())
    << "\n";
  auto write_bytes = [&](const fs::path& p, const std::string& a, const std::string& b) {
    write_atomically(p, [&](const fs::path& tmp) {
      std::ofstream f(tmp, std::ios::binary);
      f.write(a.data(), static_cast<std::streamsize>(a.size()));
      f.write(b.data(), static_cast<std::streamsize>(b.size()));
      f.close();
      if (!f) throw Error(p.string() + ": write failed (disk full?)");
    });
  };
  if (local) {
    write_bytes(path, h.str(), z);
  } else {
    write_bytes(data_path, z, "");  // the data first: the header never names missing data
    write_bytes(path, h.str(), "");
  }
}

}  // namespace mvtwin
