// NRRD reading and writing (http://teem.sourceforge.net/nrrd/format.html), with 3D Slicer's
// sequence conventions for 3D+t.
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
#include "mvtwin/core/version.h"
#include "raw_voxels.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;
using raw::VoxelType;

using raw::lower;
using raw::trim;

VoxelType nrrd_type(const std::string& name, const std::string& what) {
  const std::string t = lower(trim(name));
  if (t == "uchar" || t == "unsigned char" || t == "uint8" || t == "uint8_t") return VoxelType::kU8;
  if (t == "signed char" || t == "int8" || t == "int8_t") return VoxelType::kI8;
  if (t == "short" || t == "short int" || t == "signed short" || t == "signed short int" ||
      t == "int16" || t == "int16_t")
    return VoxelType::kI16;
  if (t == "ushort" || t == "unsigned short" || t == "unsigned short int" || t == "uint16" ||
      t == "uint16_t")
    return VoxelType::kU16;
  if (t == "int" || t == "signed int" || t == "int32" || t == "int32_t") return VoxelType::kI32;
  if (t == "uint" || t == "unsigned int" || t == "uint32" || t == "uint32_t")
    return VoxelType::kU32;
  if (t == "float") return VoxelType::kF32;
  if (t == "double") return VoxelType::kF64;
  throw Error(what + ": unsupported NRRD type '" + trim(name) + "'");
}

/// "(x,y,z)" or "none" tokens of a vector list such as "space directions".
std::vector<std::string> vector_tokens(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  int depth = 0;
  for (char c : s) {
    if (c == '(') ++depth;
    if (c == ')') --depth;
    if (std::isspace(static_cast<unsigned char>(c)) && depth == 0) {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else if (!std::isspace(static_cast<unsigned char>(c))) {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

Eigen::Vector3d parse_vector(const std::string& token, const std::string& what) {
  if (token.size() < 2 || token.front() != '(' || token.back() != ')')
    throw Error(what + ": expected a vector like (1,0,0), found '" + token + "'");
  std::stringstream ss(token.substr(1, token.size() - 2));
  Eigen::Vector3d v;
  std::string part;
  int k = 0;
  while (std::getline(ss, part, ',')) {
    if (k == 3) throw Error(what + ": vector '" + token + "' has more than 3 components");
    v[k++] = raw::number(part, what);
  }
  if (k != 3) throw Error(what + ": vector '" + token + "' has fewer than 3 components");
  if (!v.allFinite()) throw Error(what + ": vector '" + token + "' is not finite");
  return v;
}

/// The sign flips from the file's space to RAS.
Eigen::Vector3d space_to_ras(const std::string& space, const std::string& what) {
  const std::string s = lower(trim(space));
  if (s == "right-anterior-superior" || s == "ras" || s == "3d-right-handed" || s == "scanner-xyz")
    return {1, 1, 1};
  if (s == "left-posterior-superior" || s == "lps") return {-1, -1, 1};
  if (s == "left-anterior-superior" || s == "las") return {-1, 1, 1};
  throw Error(what + ": unsupported NRRD space '" + trim(space) + "' (RAS, LPS or LAS)");
}

std::string format_vector(const Eigen::Vector3d& v) {
  std::string s = "(";
  for (int k = 0; k < 3; ++k) {
    s += raw::format_number(v[k]);
    s += k < 2 ? ',' : ')';
  }
  return s;
}

}  // namespace

std::vector<ImageVolume> read_nrrd_series(const fs::path& path) {
  return read_nrrd_series(path, nullptr);
}

std::vector<ImageVolume> read_nrrd_series(const fs::path& path,
                                          std::map<std::string, std::string>* key_values) {
  const std::string what = path.string();
  const std::string bytes = raw::read_file_bytes(path);
  if (bytes.compare(0, 7, "NRRD000") != 0)
    throw Error(what + ": not a NRRD file (no NRRD000x magic)");
  std::map<std::string, std::string> field, keyvalue;
  std::size_t pos = bytes.find('\n');
  if (pos == std::string::npos) throw Error(what + ": truncated NRRD header");
  ++pos;
  bool blank = false;
  while (pos < bytes.size()) {
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    const std::string line = trim(bytes.substr(pos, end - pos));
    pos = std::min(end + 1, bytes.size());
    if (line.empty()) {
      blank = true;
      break;
    }
    if (line[0] == '#') continue;
    const std::size_t kv = line.find(":=");
    const std::size_t f = line.find(": ");
    if (kv != std::string::npos && (f == std::string::npos || kv < f)) {
      keyvalue[line.substr(0, kv)] = line.substr(kv + 2);
    } else if (f != std::string::npos) {
      std::string key = lower(line.substr(0, f));
      key.erase(std::remove(key.begin(), key.end(), ' '), key.end());
      field[key] = trim(line.substr(f + 2));
    } else {
      throw Error(what + ": malformed NRRD header line '" + line + "'");
    }
  }
  auto need = [&](const std::string& key) -> const std::string& {
    const auto it = field.find(key);
    if (it == field.end()) throw Error(what + ": NRRD header lacks the '" + key + "' field");
    return it->second;
  };
  const VoxelType type = nrrd_type(need("type"), what);
  const int dim =
      static_cast<int>(raw::whole_number(need("dimension"), what + " (dimension)", 0, 64));
  if (dim != 3 && dim != 4)
    throw Error(what + ": expected a 3D or 3D+t image, found dimension " + std::to_string(dim));
  const std::vector<std::string> size_words = raw::words(need("sizes"));
  if (static_cast<int>(size_words.size()) != dim)
    throw Error(what + ": 'sizes' has " + std::to_string(size_words.size()) + " entries for " +
                std::to_string(dim) + " dimensions");
  std::vector<long> sizes;
  for (const auto& w : size_words) {
    const double v = raw::number(w, what + " (sizes)");
    if (!(v >= 1 && v < 1e6 && v == std::floor(v))) throw Error(what + ": bad size '" + w + "'");
    sizes.push_back(static_cast<long>(v));
  }

  // Geometry: the spatial axes (space directions that are not "none") and the frame axis.
  Eigen::Vector3d flip(1, 1, 1);
  if (field.count("space")) flip = space_to_ras(field["space"], what);
  std::vector<int> spatial;
  int frame_axis = -1;
  ImageVolume geom;
  if (field.count("spacedirections")) {
    const std::vector<std::string> t = vector_tokens(field["spacedirections"]);
    if (static_cast<int>(t.size()) != dim)
      throw Error(what + ": 'space directions' has " + std::to_string(t.size()) + " entries for " +
                  std::to_string(dim) + " dimensions");
    for (int a = 0; a < dim; ++a) {
      if (lower(t[a]) == "none") {
        if (frame_axis >= 0) throw Error(what + ": more than one non-spatial axis");
        frame_axis = a;
        continue;
      }
      const Eigen::Vector3d d = flip.cwiseProduct(parse_vector(t[a], what + " (space directions)"));
      const int k = static_cast<int>(spatial.size());
      if (k == 3) throw Error(what + ": more than 3 spatial axes");
      geom.spacing[k] = d.norm();
      if (!(geom.spacing[k] > 0)) throw Error(what + ": a space direction has zero length");
      geom.direction.col(k) = d / geom.spacing[k];
      spatial.push_back(a);
    }
  } else {
    // No space: axis-aligned, "spacings" (nan for a non-spatial axis).
    std::vector<std::string> sp;
    if (field.count("spacings")) sp = raw::words(field["spacings"]);
    for (int a = 0; a < dim; ++a) {
      const double s =
          a < static_cast<int>(sp.size()) ? raw::number(sp[a], what + " (spacings)") : 1.0;
      const bool list = field.count("kinds") &&
                        a < static_cast<int>(raw::words(field["kinds"]).size()) &&
                        (lower(raw::words(field["kinds"])[a]) == "list" ||
                         lower(raw::words(field["kinds"])[a]) == "time");
      if (dim == 4 && (list || !std::isfinite(s)) && frame_axis < 0) {
        frame_axis = a;
        continue;
      }
      const int k = static_cast<int>(spatial.size());
      if (k == 3) throw Error(what + ": more than 3 spatial axes");
      if (!(s > 0)) throw Error(what + ": spacing '" + sp[a] + "' is not positive");
      geom.spacing[k] = s;
      spatial.push_back(a);
    }
  }
  if (spatial.size() != 3) throw Error(what + ": expected 3 spatial axes");
  if (dim == 4 && frame_axis != 0 && frame_axis != 3)
    throw Error(what + ": the frame axis must be the first or the last");
  if (field.count("spaceorigin")) {
    geom.origin = flip.cwiseProduct(parse_vector(field["spaceorigin"], what + " (space origin)"));
  }
  for (int k = 0; k < 3; ++k) geom.size[k] = static_cast<int>(sizes[spatial[k]]);
  const long nt = frame_axis >= 0 ? sizes[frame_axis] : 1;
  const std::size_t nvox = geom.num_voxels(), total = nvox * static_cast<std::size_t>(nt);

  // The data: attached after the blank line, or detached.
  std::string data;
  if (field.count("datafile")) {
    const std::string df = field["datafile"];
    if (df.rfind("LIST", 0) == 0 || df.find('%') != std::string::npos || raw::words(df).size() > 1)
      throw Error(what + ": multi-file NRRD data ('" + df + "') is not supported");
    fs::path dp = df;
    if (dp.is_relative()) dp = path.parent_path() / dp;
    data = raw::read_file_bytes(dp);
  } else {
    if (!blank) throw Error(what + ": NRRD header has no data (no blank line and no 'data file')");
    data = bytes.substr(pos);
  }
  if (field.count("lineskip")) {
    const long skip = raw::whole_number(field["lineskip"], what + " (line skip)", 0, 1L << 40);
    std::size_t p = 0;
    for (long i = 0; i < skip; ++i) {
      p = data.find('\n', p);
      if (p == std::string::npos) throw Error(what + ": 'line skip' goes past the data");
      ++p;
    }
    data.erase(0, p);
  }
  const std::string encoding = field.count("encoding") ? lower(field["encoding"]) : "raw";
  const long byte_skip =
      field.count("byteskip")
          ? raw::whole_number(field["byteskip"], what + " (byte skip)", -1, 1L << 50)
          : 0;
  const std::size_t need_bytes = total * static_cast<std::size_t>(raw::bytes_of(type));
  std::vector<float> values;
  if (encoding == "raw" || encoding == "gzip" || encoding == "gz") {
    if (encoding != "raw") {
      if (byte_skip != 0) throw Error(what + ": 'byte skip' with gzip encoding is not supported");
      data = raw::inflate(data, need_bytes, what);
    } else if (byte_skip == -1) {
      if (data.size() < need_bytes) throw Error(what + ": truncated voxel data");
      data.erase(0, data.size() - need_bytes);
    } else if (byte_skip > 0) {
      if (static_cast<std::size_t>(byte_skip) > data.size())
        throw Error(what + ": 'byte skip' goes past the data");
      data.erase(0, static_cast<std::size_t>(byte_skip));
    }
    if (data.size() < need_bytes) {
      throw Error(what + ": truncated voxel data (expected " + std::to_string(need_bytes) +
                  " bytes, found " + std::to_string(data.size()) + ")");
    }
    const bool big = field.count("endian") && lower(field["endian"]) == "big";
    values = raw::decode(data, type, big, total);
  } else if (encoding == "ascii" || encoding == "text" || encoding == "txt") {
    std::istringstream is(data);
    values.resize(total);
    for (std::size_t i = 0; i < total; ++i) {
      double v;
      if (!(is >> v))
        throw Error(what + ": ascii data ends after " + std::to_string(i) + " values");
      values[i] = static_cast<float>(v);
    }
  } else {
    throw Error(what + ": unsupported NRRD encoding '" + field["encoding"] +
                "' (raw, gzip, ascii)");
  }

  // Frame times: Slicer's per-item index values, else the axis spacing, else the frame index.
  std::vector<double> times(static_cast<std::size_t>(nt), 0.0);
  if (frame_axis >= 0) {
    const std::string key = "axis " + std::to_string(frame_axis) + " index values";
    std::vector<std::string> tv;
    if (keyvalue.count(key)) tv = raw::words(keyvalue[key]);
    double dt = 1.0;
    if (field.count("spacings")) {
      const auto sp = raw::words(field["spacings"]);
      if (frame_axis < static_cast<int>(sp.size())) {
        const double s = raw::number(sp[frame_axis], what + " (spacings)");
        if (std::isfinite(s) && s > 0) dt = s;
      }
    }
    // Slicer writes the index unit beside the values ("s", or "ms" for some ultrasound
    // sequences); times are kept in s.
    const std::string unit_key = "axis " + std::to_string(frame_axis) + " index unit";
    const double scale =
        keyvalue.count(unit_key) && lower(trim(keyvalue[unit_key])) == "ms" ? 1e-3 : 1.0;
    for (long f = 0; f < nt; ++f) {
      times[f] = static_cast<long>(tv.size()) == nt
                     ? scale * raw::number(tv[f], what + " (" + key + ")")
                     : f * dt;
    }
  }
  if (key_values) *key_values = keyvalue;
  std::vector<ImageVolume> out;
  for (long f = 0; f < nt; ++f) {
    ImageVolume im = geom;
    im.time_s = times[f];
    im.data.resize(nvox);
    if (frame_axis == 0) {
      for (std::size_t v = 0; v < nvox; ++v)
        im.data[v] = values[static_cast<std::size_t>(f) + nt * v];
    } else {
      std::copy_n(values.begin() + static_cast<long>(nvox) * f, nvox, im.data.begin());
    }
    out.push_back(std::move(im));
  }
  return out;
}

void write_nrrd_series(const fs::path& path, const std::vector<ImageVolume>& s) {
  const std::string what = path.string();
  const bool series = s.size() > 1;
  const std::size_t nvox = s.front().num_voxels();
  std::ostringstream h;
  h << "NRRD0004\n# written by mvtwin " << kVersion << "; space RAS, mm; times in s\n"
    << "type: float\ndimension: " << (series ? 4 : 3) << "\nspace: right-anterior-superior\n";
  h << "sizes:";
  if (series) h << " " << s.size();
  for (int k = 0; k < 3; ++k) h << " " << s.front().size[k];
  h << "\nspace directions:" << (series ? " none" : "");
  for (int k = 0; k < 3; ++k)
    h << " " << format_vector(Eigen::Vector3d(s.front().direction.col(k) * s.front().spacing[k]));
  h << "\nkinds:" << (series ? " list" : "") << " domain domain domain\n";
  if (series) h << "labels: \"time\" \"\" \"\" \"\"\n";
  h << "endian: little\nencoding: gzip\nspace origin: " << format_vector(s.front().origin) << "\n";
  if (series) {
    h << "axis 0 index type:=numeric\naxis 0 index values:=";
    for (std::size_t f = 0; f < s.size(); ++f)
      h << (f ? " " : "") << raw::format_number(s[f].time_s);
    h << "\nDataNodeClassName:=vtkMRMLScalarVolumeNode\n";
  }
  h << "\n";
  std::vector<float> values(nvox * s.size());
  for (std::size_t f = 0; f < s.size(); ++f)
    for (std::size_t v = 0; v < nvox; ++v) values[f + s.size() * v] = s[f].data[v];
  const std::string z = raw::deflate(reinterpret_cast<const char*>(values.data()),
                                     values.size() * sizeof(float), true);
  write_atomically(path, [&](const fs::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << h.str();
    f.write(z.data(), static_cast<std::streamsize>(z.size()));
    f.close();
    if (!f) throw Error(what + ": write failed (disk full?)");
  });
}

}  // namespace mvtwin
