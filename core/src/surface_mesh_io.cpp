#include "mvtwin/core/surface_mesh_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include <Eigen/Geometry>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "raw_voxels.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;
using raw::lower;
using raw::trim;

std::string space_mark(const std::string& text) {
  const std::string u = lower(text);
  if (u.find("space=lps") != std::string::npos) return "LPS";
  if (u.find("space=ras") != std::string::npos) return "RAS";
  return "";
}

bool host_little() {
  const std::uint16_t x = 1;
  std::uint8_t b;
  std::memcpy(&b, &x, 1);
  return b == 1;
}

/// Reads a value of `bytes` bytes at p with the given byte order, as a double (integers exact
/// up to 2^53).
double read_value(const char* p, const std::string& type, bool big) {
  char buf[8];
  int n = 4;
  if (type == "float64" || type == "double" || type == "int64" || type == "uint64") n = 8;
  if (type == "int16" || type == "uint16" || type == "short" || type == "ushort") n = 2;
  if (type == "int8" || type == "uint8" || type == "char" || type == "uchar") n = 1;
  std::memcpy(buf, p, static_cast<size_t>(n));
  if (big == host_little()) std::reverse(buf, buf + n);
  if (type == "float32" || type == "float") {
    float v;
    std::memcpy(&v, buf, 4);
    return v;
  }
  if (type == "float64" || type == "double") {
    double v;
    std::memcpy(&v, buf, 8);
    return v;
  }
  if (type == "int32" || type == "int") {
    std::int32_t v;
    std::memcpy(&v, buf, 4);
    return v;
  }
  if (type == "uint32" || type == "uint") {
    std::uint32_t v;
    std::memcpy(&v, buf, 4);
    return v;
  }
  if (type == "int64") {
    std::int64_t v;
    std::memcpy(&v, buf, 8);
    return static_cast<double>(v);
  }
  if (type == "uint64") {
    std::uint64_t v;
    std::memcpy(&v, buf, 8);
    return static_cast<double>(v);
  }
  if (type == "int16" || type == "short") {
    std::int16_t v;
    std::memcpy(&v, buf, 2);
    return v;
  }
  if (type == "uint16" || type == "ushort") {
    std::uint16_t v;
    std::memcpy(&v, buf, 2);
    return v;
  }
  if (type == "int8" || type == "char") return static_cast<std::int8_t>(buf[0]);
  return static_cast<std::uint8_t>(buf[0]);
}

std::string vtk_type(std::string t) {
  t = lower(t);
  if (t.rfind("vtktype", 0) == 0) t = t.substr(7);  // VTK 5.1: vtktypeint64
  if (t == "vtkidtype") t = "int32";
  return t;
}

int type_size(const std::string& type_in, const std::string& what) {
  const std::string type = vtk_type(type_in);
  static const std::map<std::string, int> size = {
      {"float32", 4}, {"float", 4},  {"float64", 8}, {"double", 8}, {"int32", 4}, {"int", 4},
      {"uint32", 4},  {"uint", 4},   {"int64", 8},   {"uint64", 8}, {"int16", 2}, {"short", 2},
      {"uint16", 2},  {"ushort", 2}, {"int8", 1},    {"char", 1},   {"uint8", 1}, {"uchar", 1}};
  const auto it = size.find(lower(type));
  if (it == size.end()) throw Error(what + ": unsupported value type '" + type + "'");
  return it->second;
}

/// Base64 decoding that continues across '=' padding (VTK encodes a header and its data as
/// separate base64 blocks).
std::string base64_decode(const std::string& in, const std::string& what) {
  auto val = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::string out;
  int q[4], n = 0, pad = 0;
  for (char c : in) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    if (c == '=') {
      q[n++] = 0;
      ++pad;
    } else {
      const int v = val(c);
      if (v < 0) throw Error(what + ": invalid base64 data");
      q[n++] = v;
    }
    if (n == 4) {
      const std::uint32_t w =
          (static_cast<std::uint32_t>(q[0]) << 18) | (static_cast<std::uint32_t>(q[1]) << 12) |
          (static_cast<std::uint32_t>(q[2]) << 6) | static_cast<std::uint32_t>(q[3]);
      out += static_cast<char>((w >> 16) & 0xFF);
      if (pad < 2) out += static_cast<char>((w >> 8) & 0xFF);
      if (pad < 1) out += static_cast<char>(w & 0xFF);
      n = 0;
      pad = 0;
    }
  }
  if (n != 0) throw Error(what + ": truncated base64 data");
  return out;
}

std::string base64_encode(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t w = (static_cast<std::uint8_t>(in[i]) << 16) |
                            (static_cast<std::uint8_t>(in[i + 1]) << 8) |
                            static_cast<std::uint8_t>(in[i + 2]);
    out += t[(w >> 18) & 63];
    out += t[(w >> 12) & 63];
    out += t[(w >> 6) & 63];
    out += t[w & 63];
  }
  if (i < in.size()) {
    std::uint32_t w = static_cast<std::uint8_t>(in[i]) << 16;
    if (i + 1 < in.size()) w |= static_cast<std::uint8_t>(in[i + 1]) << 8;
    out += t[(w >> 18) & 63];
    out += t[(w >> 12) & 63];
    out += i + 1 < in.size() ? t[(w >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

/// Polygons (vertex lists) fanned into triangles, checked against the vertex count.
void add_polygon(const std::vector<long>& poly, long nv, std::vector<Eigen::Vector3i>* tris,
                 const std::string& what) {
  for (long v : poly)
    if (v < 0 || v >= nv)
      throw Error(what + ": a polygon refers to vertex " + std::to_string(v) + " of " +
                  std::to_string(nv));
  for (size_t k = 1; k + 1 < poly.size(); ++k)
    tris->emplace_back(static_cast<int>(poly[0]), static_cast<int>(poly[k]),
                       static_cast<int>(poly[k + 1]));
}

void add_strip(const std::vector<long>& s, long nv, std::vector<Eigen::Vector3i>* tris,
               const std::string& what) {
  for (long v : s)
    if (v < 0 || v >= nv)
      throw Error(what + ": a strip refers to vertex " + std::to_string(v) + " of " +
                  std::to_string(nv));
  for (size_t k = 0; k + 2 < s.size(); ++k) {
    if (k % 2 == 0)
      tris->emplace_back(static_cast<int>(s[k]), static_cast<int>(s[k + 1]),
                         static_cast<int>(s[k + 2]));
    else
      tris->emplace_back(static_cast<int>(s[k + 1]), static_cast<int>(s[k]),
                         static_cast<int>(s[k + 2]));
  }
}

TriangleMesh make_mesh(const std::vector<Eigen::Vector3d>& V, const std::vector<Eigen::Vector3i>& F,
                       const std::string& what) {
  if (F.empty()) throw Error(what + ": the surface has no triangles");
  TriangleMesh m;
  m.V.resize(static_cast<Eigen::Index>(V.size()), 3);
  for (size_t i = 0; i < V.size(); ++i) {
    if (!V[i].allFinite())
      throw Error(what + ": vertex " + std::to_string(i) + " has a NaN/Inf coordinate");
    m.V.row(static_cast<Eigen::Index>(i)) = V[i].transpose();
  }
  m.F.resize(static_cast<Eigen::Index>(F.size()), 3);
  for (size_t i = 0; i < F.size(); ++i) m.F.row(static_cast<Eigen::Index>(i)) = F[i].transpose();
  m.check(what.c_str());
  return m;
}

SurfaceFile read_stl(const std::string& bytes, const std::string& what) {
  SurfaceFile out;
  std::vector<Eigen::Vector3d> corners;
  const bool binary_size = bytes.size() >= 84 && [&] {
    std::uint32_t n;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (!host_little()) n = __builtin_bswap32(n);
    return bytes.size() == 84 + 50ull * n;
  }();
  if (binary_size) {
    out.space = space_mark(bytes.substr(0, 80));
    std::uint32_t n;
    std::memcpy(&n, bytes.data() + 80, 4);
    if (!host_little()) n = __builtin_bswap32(n);
    for (std::uint32_t t = 0; t < n; ++t)
      for (int c = 0; c < 3; ++c) {
        const char* p = bytes.data() + 84 + 50 * t + 12 + 12 * c;
        corners.emplace_back(read_value(p, "float32", false), read_value(p + 4, "float32", false),
                             read_value(p + 8, "float32", false));
      }
  } else {
    if (lower(bytes.substr(0, 5)) != "solid")
      throw Error(what +
                  ": neither an ASCII STL file (\"solid\") nor a binary one of consistent size");
    out.space = space_mark(bytes.substr(0, bytes.find('\n')));
    std::istringstream is(bytes);
    std::string word;
    while (is >> word) {
      if (lower(word) != "vertex") continue;
      Eigen::Vector3d p;
      if (!(is >> p.x() >> p.y() >> p.z())) throw Error(what + ": a vertex line has no 3 numbers");
      corners.push_back(p);
    }
    if (corners.size() % 3) throw Error(what + ": the facets do not have 3 vertices each");
  }
  // Merge coincident corners so that triangles share vertices.
  std::map<std::array<double, 3>, int> index;
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  std::vector<int> id(corners.size());
  for (size_t i = 0; i < corners.size(); ++i) {
    const std::array<double, 3> key = {corners[i].x(), corners[i].y(), corners[i].z()};
    auto [it, added] = index.emplace(key, static_cast<int>(V.size()));
    if (added) V.push_back(corners[i]);
    id[i] = it->second;
  }
  for (size_t t = 0; t + 2 < corners.size(); t += 3)
    if (id[t] != id[t + 1] && id[t + 1] != id[t + 2] && id[t] != id[t + 2])
      F.emplace_back(id[t], id[t + 1], id[t + 2]);
  out.mesh = make_mesh(V, F, what);
  return out;
}

SurfaceFile read_ply(const std::string& bytes, const std::string& what) {
  SurfaceFile out;
  const size_t end = bytes.find("end_header");
  if (bytes.compare(0, 3, "ply") != 0 || end == std::string::npos)
    throw Error(what + ": not a PLY file (no ply ... end_header)");
  const std::string header = bytes.substr(0, end);
  out.space = space_mark(header);
  size_t pos = bytes.find('\n', end);
  if (pos == std::string::npos) throw Error(what + ": truncated PLY header");
  ++pos;
  struct Prop {
    std::string name, type, count_type;
    bool list = false;
  };
  struct Element {
    std::string name;
    long count = 0;
    std::vector<Prop> props;
  };
  std::vector<Element> elements;
  std::string format;
  std::istringstream hs(header);
  std::string line;
  while (std::getline(hs, line)) {
    const auto w = raw::words(line);
    if (w.empty()) continue;
    if (w[0] == "format" && w.size() >= 2) format = w[1];
    if (w[0] == "element" && w.size() >= 3) elements.push_back({w[1], std::stol(w[2]), {}});
    if (w[0] == "property" && !elements.empty()) {
      if (w.size() >= 5 && w[1] == "list")
        elements.back().props.push_back({w[4], lower(w[3]), lower(w[2]), true});
      else if (w.size() >= 3)
        elements.back().props.push_back({w[2], lower(w[1]), "", false});
    }
  }
  if (format != "ascii" && format != "binary_little_endian" && format != "binary_big_endian")
    throw Error(what + ": unsupported PLY format '" + format + "'");
  const bool big = format == "binary_big_endian";
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  std::istringstream as(format == "ascii" ? bytes.substr(pos) : std::string());
  auto next = [&](const std::string& type) -> double {
    if (format == "ascii") {
      std::string tok;
      if (!(as >> tok)) throw Error(what + ": PLY data ends early");
      char* e = nullptr;
      const double v = std::strtod(tok.c_str(), &e);
      if (e == tok.c_str() || *e != '\0')
        throw Error(what + ": '" + tok + "' in the PLY data is not a number");
      return v;
    }
    const int n = type_size(type, what);
    if (pos + static_cast<size_t>(n) > bytes.size()) throw Error(what + ": PLY data ends early");
    const double v = read_value(bytes.data() + pos, type, big);
    pos += static_cast<size_t>(n);
    return v;
  };
  long nv = -1;
  for (const Element& e : elements) {
    if (e.count < 0 || e.count > 100000000) throw Error(what + ": implausible element count");
    for (long i = 0; i < e.count; ++i) {
      Eigen::Vector3d p = Eigen::Vector3d::Constant(std::nan(""));
      std::vector<long> poly;
      for (const Prop& pr : e.props) {
        if (pr.list) {
          const long n = raw::whole(next(pr.count_type), what + " (polygon size)", 0, 1000);
          for (long k = 0; k < n; ++k)
            poly.push_back(raw::whole(next(pr.type), what + " (vertex index)", 0, 1L << 40));
        } else {
          const double v = next(pr.type);
          if (pr.name == "x") p.x() = v;
          if (pr.name == "y") p.y() = v;
          if (pr.name == "z") p.z() = v;
        }
      }
      if (e.name == "vertex") V.push_back(p);
      if (e.name == "face") add_polygon(poly, nv, &F, what);
    }
    if (e.name == "vertex") nv = static_cast<long>(V.size());
  }
  out.mesh = make_mesh(V, F, what);
  return out;
}

SurfaceFile read_vtk_legacy(const std::string& bytes, const std::string& what) {
  SurfaceFile out;
  size_t pos = 0;
  auto getline = [&]() -> std::string {
    if (pos >= bytes.size()) throw Error(what + ": truncated VTK file");
    size_t e = bytes.find('\n', pos);
    if (e == std::string::npos) e = bytes.size();
    std::string l = bytes.substr(pos, e - pos);
    pos = e + 1;
    return trim(l);
  };
  if (getline().find("vtk DataFile") == std::string::npos)
    throw Error(what + ": not a legacy VTK file");
  out.space = space_mark(getline());
  const std::string mode = lower(getline());
  const bool binary = mode == "binary";
  if (!binary && mode != "ascii") throw Error(what + ": VTK mode must be ASCII or BINARY");
  std::string l;
  do l = getline();
  while (l.empty());
  if (lower(l) != "dataset polydata")
    throw Error(what + ": not POLYDATA ('" + l + "'); a surface is expected");
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> F;
  auto read_numbers = [&](long n, const std::string& type) {
    std::vector<double> v(static_cast<size_t>(n));
    if (binary) {
      const int s = type_size(type, what);
      if (pos + static_cast<size_t>(n) * static_cast<size_t>(s) > bytes.size())
        throw Error(what + ": truncated VTK data");
      for (long i = 0; i < n; ++i)
        v[static_cast<size_t>(i)] =
            read_value(bytes.data() + pos + static_cast<size_t>(i) * s, vtk_type(type), true);
      pos += static_cast<size_t>(n) * static_cast<size_t>(s);
      if (pos < bytes.size() && bytes[pos] == '\n') ++pos;
    } else {
      for (long i = 0; i < n; ++i) {
        while (pos < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
        const char* b = bytes.c_str() + pos;
        char* e = nullptr;
        v[static_cast<size_t>(i)] = std::strtod(b, &e);
        if (e == b) throw Error(what + ": VTK data ends early or is not numeric");
        pos += static_cast<size_t>(e - b);
      }
    }
    return v;
  };
  while (pos < bytes.size()) {
    l = getline();
    if (l.empty()) continue;
    const auto w = raw::words(l);
    if (w.empty()) continue;  // whitespace trim() keeps (a vertical tab: fuzz_surface_mesh)
    const std::string key = lower(w[0]);
    if (key == "points" && w.size() >= 3) {
      const long n = std::stol(w[1]);
      if (n < 0 || n > 50000000) throw Error(what + ": implausible point count " + w[1]);
      const auto v = read_numbers(3 * n, lower(w[2]));
      for (long i = 0; i < n; ++i) V.emplace_back(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    } else if ((key == "polygons" || key == "triangle_strips" || key == "vertices" ||
                key == "lines") &&
               w.size() >= 3) {
      const long a = std::stol(w[1]), b = std::stol(w[2]);
      if (a < 0 || b < 0 || a > 100000000 || b > 400000000)
        throw Error(what + ": implausible cell counts '" + l + "'");
      const bool strips = key == "triangle_strips", use = key == "polygons" || strips;
      // VTK 5.1 layout: "POLYGONS n_offsets n_connectivity", then OFFSETS and CONNECTIVITY arrays.
      const size_t save = pos;
      std::string nextl;
      while (pos < bytes.size() && (nextl = getline()).empty()) {
      }
      if (lower(nextl).rfind("offsets", 0) == 0) {
        const auto ow = raw::words(nextl);
        const auto off = read_numbers(a, ow.size() > 1 ? lower(ow[1]) : "int64");
        std::string cl;
        while ((cl = getline()).empty()) {
        }
        const auto cw = raw::words(cl);
        const auto con = read_numbers(b, cw.size() > 1 ? lower(cw[1]) : "int64");
        const long ncon = static_cast<long>(con.size());
        for (long c = 0; c + 1 < a; ++c) {
          std::vector<long> poly;
          const long first = raw::whole(off[c], what + " (offsets)", 0, ncon);
          const long last = raw::whole(off[c + 1], what + " (offsets)", first, ncon);
          for (long k = first; k < last; ++k)
            poly.push_back(raw::whole(con[k], what + " (connectivity)", 0, 1L << 40));
          if (use)
            strips ? add_strip(poly, static_cast<long>(V.size()), &F, what)
                   : add_polygon(poly, static_cast<long>(V.size()), &F, what);
        }
      } else {
        pos = save;
        const auto v = read_numbers(b, "int32");
        size_t k = 0;
        for (long c = 0; c < a; ++c) {
          if (k >= v.size()) throw Error(what + ": cell list ends early");
          const long n = raw::whole(v[k++], what + " (cell size)", 0, 1L << 40);
          if (n < 0 || k + static_cast<size_t>(n) > v.size())
            throw Error(what + ": bad cell size " + std::to_string(n));
          std::vector<long> poly;
          for (long j = 0; j < n; ++j)
            poly.push_back(raw::whole(v[k++], what + " (cell)", 0, 1L << 40));
          if (use)
            strips ? add_strip(poly, static_cast<long>(V.size()), &F, what)
                   : add_polygon(poly, static_cast<long>(V.size()), &F, what);
        }
      }
    } else if (key == "point_data" || key == "cell_data" || key == "field") {
      break;  // attributes are not needed
    }
  }
  out.mesh = make_mesh(V, F, what);
  return out;
}

std::string attr(const std::string& tag, const std::string& name) {
  const size_t p = tag.find(" " + name + "=\"");
  if (p == std::string::npos) return "";
  const size_t b = p + name.size() + 3, e = tag.find('"', b);
  return tag.substr(b, e - b);
}

SurfaceFile read_vtp(const std::string& bytes, const std::string& what) {
  SurfaceFile out;
  const size_t vt = bytes.find("<VTKFile");
  if (vt == std::string::npos) throw Error(what + ": not a VTK XML file");
  const std::string vtk_tag = bytes.substr(vt, bytes.find('>', vt) - vt);
  if (attr(vtk_tag, "type") != "PolyData")
    throw Error(what + ": not VTK PolyData (type '" + attr(vtk_tag, "type") + "')");
  const bool big = attr(vtk_tag, "byte_order") == "BigEndian";
  const std::string header_type =
      lower(attr(vtk_tag, "header_type").empty() ? "UInt32" : attr(vtk_tag, "header_type"));
  const bool compressed = attr(vtk_tag, "compressor").find("ZLib") != std::string::npos;
  if (!attr(vtk_tag, "compressor").empty() && !compressed)
    throw Error(what + ": unsupported compressor '" + attr(vtk_tag, "compressor") +
                "' (zlib only)");
  const size_t appended = bytes.find("<AppendedData");
  out.space = space_mark(bytes.substr(0, appended == std::string::npos ? bytes.size() : appended));
  std::string app_data;
  bool app_base64 = false;
  if (appended != std::string::npos) {
    const std::string tag = bytes.substr(appended, bytes.find('>', appended) - appended);
    app_base64 = attr(tag, "encoding") == "base64";
    const size_t us = bytes.find('_', bytes.find('>', appended));
    if (us == std::string::npos) throw Error(what + ": AppendedData without its '_' mark");
    app_data = bytes.substr(us + 1);
  }
  const int hs = header_type == "uint64" ? 8 : 4;
  // The bytes of one binary array (after its header), from a buffer that starts at its header.
  auto binary_array = [&](const std::string& buf, size_t at, bool base64_each) -> std::string {
    auto header_value = [&](const std::string& b, size_t p) {
      return static_cast<size_t>(read_value(b.data() + p, header_type, big));
    };
    if (!compressed) {
      std::string b = base64_each ? base64_decode(buf.substr(at), what) : buf.substr(at);
      if (b.size() < static_cast<size_t>(hs)) throw Error(what + ": truncated array");
      const size_t n = header_value(b, 0);
      if (b.size() < hs + n) throw Error(what + ": truncated array");
      return b.substr(static_cast<size_t>(hs), n);
    }
    // zlib: [nblocks][blocksize][lastsize][csize x nblocks], then the blocks.
    // Any prefix of base64 text whose length is a multiple of 4 decodes to a prefix of the bytes.
    std::string head = base64_each
                           ? base64_decode(buf.substr(at, 4 * static_cast<size_t>(hs)), what)
                           : buf.substr(at, 3 * static_cast<size_t>(hs));
    if (head.size() < 3 * static_cast<size_t>(hs))
      throw Error(what + ": truncated compressed array header");
    const size_t nb = header_value(head, 0), bs = header_value(head, static_cast<size_t>(hs)),
                 last = header_value(head, 2 * static_cast<size_t>(hs));
    if (nb > 100000) throw Error(what + ": implausible block count");
    const size_t full_head = static_cast<size_t>(hs) * (3 + nb);
    std::string all;
    if (base64_each) {
      const size_t head_chars = 4 * ((full_head + 2) / 3);
      head = base64_decode(buf.substr(at, head_chars), what);
      all = head + base64_decode(buf.substr(at + head_chars), what);
    } else {
      all = buf.substr(at);
    }
    if (all.size() < full_head) throw Error(what + ": truncated compressed array");
    std::string data;
    size_t p = full_head;
    for (size_t k = 0; k < nb; ++k) {
      const size_t cs = header_value(all, static_cast<size_t>(hs) * (3 + k));
      if (p + cs > all.size()) throw Error(what + ": truncated compressed block");
      data += raw::inflate(all.substr(p, cs), k + 1 == nb && last > 0 ? last : bs, what);
      p += cs;
    }
    return data;
  };
  auto read_array = [&](const std::string& tag, const std::string& body, size_t count) {
    const std::string type = lower(attr(tag, "type"));
    const std::string format = attr(tag, "format");
    std::vector<double> v;
    if (format == "ascii") {
      std::istringstream is(body);
      double x;
      while (v.size() < count && is >> x) v.push_back(x);
    } else {
      std::string data;
      if (format == "binary") {
        std::string clean;
        for (char c : body)
          if (!std::isspace(static_cast<unsigned char>(c))) clean += c;
        data = binary_array(clean, 0, true);
      } else if (format == "appended") {
        const size_t off = static_cast<size_t>(std::stoull(attr(tag, "offset")));
        if (off >= app_data.size()) throw Error(what + ": appended offset past the data");
        data = binary_array(app_data, off, app_base64);
      } else {
        throw Error(what + ": unsupported DataArray format '" + format + "'");
      }
      const int s = type_size(type, what);
      for (size_t i = 0;
           i * static_cast<size_t>(s) + static_cast<size_t>(s) <= data.size() && v.size() < count;
           ++i)
        v.push_back(read_value(data.data() + i * static_cast<size_t>(s), type, big));
    }
    if (v.size() < count)
      throw Error(what + ": a DataArray has " + std::to_string(v.size()) + " values, " +
                  std::to_string(count) + " expected");
    return v;
  };
  // Arrays inside an element (<Points>, <Polys>, <Strips>) of the first piece.
  auto arrays_in = [&](const std::string& element) {
    std::map<std::string, std::pair<std::string, std::string>> out_arrays;  // name -> (tag, body)
    const size_t b = bytes.find("<" + element + ">");
    if (b == std::string::npos || (appended != std::string::npos && b > appended))
      return out_arrays;
    const size_t e = bytes.find("</" + element + ">", b);
    size_t p = b;
    int unnamed = 0;
    while ((p = bytes.find("<DataArray", p)) != std::string::npos && p < e) {
      const size_t te = bytes.find('>', p);
      // Without its '>' the search started over from the file's beginning, for ever
      // (fuzz_surface_mesh's third 10-minute run).
      if (te == std::string::npos) throw Error(what + ": a <DataArray tag is not closed by '>'");
      const std::string tag = bytes.substr(p, te - p + 1);
      std::string body;
      size_t next = te + 1;
      if (tag[tag.size() - 2] != '/') {
        const size_t close = bytes.find("</DataArray>", te);
        if (close == std::string::npos) throw Error(what + ": a <DataArray> has no </DataArray>");
        body = bytes.substr(te + 1, close - te - 1);
        next = close;
      }
      std::string nm = attr(tag, "Name");
      if (nm.empty()) nm = "#" + std::to_string(unnamed++);
      out_arrays[nm] = {tag, body};
      p = next;
    }
    return out_arrays;
  };
  const size_t piece = bytes.find("<Piece");
  if (piece == std::string::npos) throw Error(what + ": no <Piece>");
  const std::string ptag = bytes.substr(piece, bytes.find('>', piece) - piece);
  const size_t np = static_cast<size_t>(
      std::stoull(attr(ptag, "NumberOfPoints").empty() ? "0" : attr(ptag, "NumberOfPoints")));
  const size_t npolys = static_cast<size_t>(
      std::stoull(attr(ptag, "NumberOfPolys").empty() ? "0" : attr(ptag, "NumberOfPolys")));
  const size_t nstrips = static_cast<size_t>(
      std::stoull(attr(ptag, "NumberOfStrips").empty() ? "0" : attr(ptag, "NumberOfStrips")));
  if (np > 50000000 || npolys > 100000000 || nstrips > 100000000)
    throw Error(what + ": implausible sizes");
  auto pts = arrays_in("Points");
  if (pts.empty()) throw Error(what + ": no <Points>");
  const auto& [ptag2, pbody] = pts.begin()->second;
  const auto pv = read_array(ptag2, pbody, 3 * np);
  std::vector<Eigen::Vector3d> V;
  for (size_t i = 0; i < np; ++i) V.emplace_back(pv[3 * i], pv[3 * i + 1], pv[3 * i + 2]);
  std::vector<Eigen::Vector3i> F;
  for (const auto& [element, count] :
       {std::pair<std::string, size_t>{"Polys", npolys}, {"Strips", nstrips}}) {
    if (count == 0) continue;
    auto a = arrays_in(element);
    if (!a.count("connectivity") || !a.count("offsets"))
      throw Error(what + ": <" + element + "> lacks connectivity or offsets");
    const auto off = read_array(a["offsets"].first, a["offsets"].second, count);
    const size_t ncon =
        static_cast<size_t>(raw::whole(off.back(), what + " (offsets)", 0, 1L << 40));
    const auto con = read_array(a["connectivity"].first, a["connectivity"].second, ncon);
    size_t start = 0;
    for (size_t c = 0; c < count; ++c) {
      const size_t stop = static_cast<size_t>(raw::whole(off[c], what + " (offsets)", 0, 1L << 40));
      if (stop < start || stop > con.size()) throw Error(what + ": bad offsets");
      std::vector<long> poly;
      for (size_t k = start; k < stop; ++k)
        poly.push_back(raw::whole(con[k], what + " (connectivity)", 0, 1L << 40));
      element == "Polys" ? add_polygon(poly, static_cast<long>(V.size()), &F, what)
                         : add_strip(poly, static_cast<long>(V.size()), &F, what);
      start = stop;
    }
  }
  out.mesh = make_mesh(V, F, what);
  return out;
}

bool ends_with(const std::string& s, const std::string& e) {
  return s.size() >= e.size() && s.compare(s.size() - e.size(), e.size(), e) == 0;
}

}  // namespace

SurfaceFile read_surface_mesh(const fs::path& path) {
  const std::string what = path.string();
  const std::string name = lower(path.filename().string());
  const std::string bytes = raw::read_file_bytes(path);
  try {
    if (ends_with(name, ".stl")) return read_stl(bytes, what);
    if (ends_with(name, ".ply")) return read_ply(bytes, what);
    if (ends_with(name, ".vtk")) return read_vtk_legacy(bytes, what);
    if (ends_with(name, ".vtp")) return read_vtp(bytes, what);
  } catch (const std::invalid_argument&) {
    throw Error(what + ": malformed header (a number was expected)");
  } catch (const std::out_of_range&) {
    throw Error(what + ": malformed header (a number is out of range)");
  }
  throw Error(what + ": unknown surface format (.stl, .ply, .vtk, .vtp)");
}

void write_surface_mesh(const fs::path& path, const TriangleMesh& m, const std::string& space,
                        bool compress) {
  const std::string what = path.string();
  const std::string name = lower(path.filename().string());
  m.check(what.c_str());
  const std::string mark = space.empty() ? "" : "SPACE=" + space;
  std::string text;
  if (ends_with(name, ".stl")) {
    std::string h = ("mvtwin " + mark).substr(0, 80);
    h.resize(80, ' ');
    text = h;
    const std::uint32_t n = static_cast<std::uint32_t>(m.F.rows());
    text.append(reinterpret_cast<const char*>(&n), 4);
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
      const Eigen::Vector3f nrm = (b - a).cross(c - a).normalized().cast<float>();
      text.append(reinterpret_cast<const char*>(nrm.data()), 12);
      for (const Eigen::Vector3d* p : {&a, &b, &c}) {
        const Eigen::Vector3f q = p->cast<float>();
        text.append(reinterpret_cast<const char*>(q.data()), 12);
      }
      text.append(2, '\0');
    }
  } else if (ends_with(name, ".ply")) {
    std::ostringstream o;
    o.precision(17);
    o << "ply\nformat ascii 1.0\ncomment written by mvtwin"
      << (mark.empty() ? "" : "\ncomment " + mark) << "\nelement vertex " << m.V.rows()
      << "\nproperty double x\nproperty double y\nproperty double z\nelement face " << m.F.rows()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (Eigen::Index i = 0; i < m.V.rows(); ++i)
      o << m.V(i, 0) << " " << m.V(i, 1) << " " << m.V(i, 2) << "\n";
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      o << "3 " << m.F(f, 0) << " " << m.F(f, 1) << " " << m.F(f, 2) << "\n";
    text = o.str();
  } else if (ends_with(name, ".vtk")) {
    std::ostringstream o;
    o.precision(17);
    o << "# vtk DataFile Version 4.2\nmvtwin surface " << mark
      << "\nASCII\nDATASET POLYDATA\nPOINTS " << m.V.rows() << " double\n";
    for (Eigen::Index i = 0; i < m.V.rows(); ++i)
      o << m.V(i, 0) << " " << m.V(i, 1) << " " << m.V(i, 2) << "\n";
    o << "POLYGONS " << m.F.rows() << " " << 4 * m.F.rows() << "\n";
    for (Eigen::Index f = 0; f < m.F.rows(); ++f)
      o << "3 " << m.F(f, 0) << " " << m.F(f, 1) << " " << m.F(f, 2) << "\n";
    text = o.str();
  } else if (ends_with(name, ".vtp")) {
    // base64 binary arrays, UInt64 headers, zlib-compressed in one block when asked.
    auto encode = [&](const std::string& data) {
      auto u64 = [](std::uint64_t v) { return std::string(reinterpret_cast<const char*>(&v), 8); };
      if (!compress) return base64_encode(u64(data.size()) + data);
      const std::string z = raw::deflate(data.data(), data.size(), false);
      return base64_encode(u64(1) + u64(data.size()) + u64(data.size()) + u64(z.size())) +
             base64_encode(z);
    };
    std::string pts, con, off;
    for (Eigen::Index i = 0; i < m.V.rows(); ++i)
      for (int k = 0; k < 3; ++k) {
        const double v = m.V(i, k);
        pts.append(reinterpret_cast<const char*>(&v), 8);
      }
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const std::int64_t v = m.F(f, k);
        con.append(reinterpret_cast<const char*>(&v), 8);
      }
      const std::int64_t o = 3 * (f + 1);
      off.append(reinterpret_cast<const char*>(&o), 8);
    }
    std::ostringstream o;
    o << "<?xml version=\"1.0\"?>\n<!-- written by mvtwin " << mark
      << " -->\n<VTKFile type=\"PolyData\" version=\"1.0\" "
      << "byte_order=\"LittleEndian\" header_type=\"UInt64\""
      << (compress ? " compressor=\"vtkZLibDataCompressor\"" : "")
      << ">\n<PolyData>\n<Piece NumberOfPoints=\"" << m.V.rows() << "\" NumberOfPolys=\""
      << m.F.rows() << "\">\n"
      << "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">\n"
      << encode(pts)
      << "\n</DataArray>\n</Points>\n<Polys>\n<DataArray type=\"Int64\" Name=\"connectivity\" "
         "format=\"binary\">\n"
      << encode(con)
      << "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"binary\">\n"
      << encode(off) << "\n</DataArray>\n</Polys>\n</Piece>\n</PolyData>\n</VTKFile>\n";
    text = o.str();
  } else {
    throw Error(what + ": unknown surface format (.stl, .ply, .vtk, .vtp)");
  }
  write_atomically(path, [&](const fs::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f.write(text.data(), static_cast<std::streamsize>(text.size()));
    f.close();
    if (!f) throw Error(what + ": write failed (disk full?)");
  });
}

}  // namespace mvtwin
