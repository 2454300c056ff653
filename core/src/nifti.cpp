#include "mvtwin/core/nifti.h"

#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include <Eigen/Geometry>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "raw_voxels.h"

namespace mvtwin {
namespace {

constexpr int kHeaderSize = 348;

struct GzFile {
  gzFile f = nullptr;
  ~GzFile() {
    if (f) gzclose(f);
  }
};

template <typename T>
T get(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) {
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  }
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

template <typename T>
void put(unsigned char* p, T v) {
  std::memcpy(p, &v, sizeof(T));  // written little-endian (x86); the magic says n+1
}

double spatial_unit_to_mm(int xyzt_units) {
  switch (xyzt_units & 7) {
    case 1:
      return 1000.0;  // metre
    case 3:
      return 1e-3;  // micron
    default:
      return 1.0;  // mm or unknown
  }
}

double time_unit_to_s(int xyzt_units) {
  switch (xyzt_units & 56) {
    case 16:
      return 1e-3;  // ms
    case 24:
      return 1e-6;  // us
    default:
      return 1.0;  // s or unknown
  }
}

}  // namespace

std::vector<ImageVolume> read_nifti_series(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(name + ": no such file");
  GzFile gz;
  gz.f = gzopen(path.c_str(), "rb");  // reads plain .nii transparently too
  if (!gz.f) throw Error(name + ": cannot be opened for reading");
  unsigned char h[kHeaderSize];
  if (gzread(gz.f, h, kHeaderSize) != kHeaderSize) {
    throw Error(name + ": too short for a NIfTI header (truncated, or not a NIfTI file)");
  }
  bool swap = false;
  const auto sizeof_hdr = get<std::int32_t>(h, false);
  if (sizeof_hdr != kHeaderSize) {
    if (get<std::int32_t>(h, true) == kHeaderSize) {
      swap = true;
    } else if (sizeof_hdr == 540 || get<std::int32_t>(h, true) == 540) {
      throw Error(name + ": NIfTI-2 files are not supported yet (convert to NIfTI-1)");
    } else {
      throw Error(name + ": not a NIfTI-1 file (sizeof_hdr = " + std::to_string(sizeof_hdr) + ")");
    }
  }
  if (std::memcmp(h + 344, "n+1", 4) != 0 && std::memcmp(h + 344, "ni1", 4) != 0) {
    throw Error(name +
                ": bad NIfTI magic (expected 'n+1'; a separate .hdr/.img pair is not supported)");
  }
  std::int16_t dim[8];
  for (int i = 0; i < 8; ++i) dim[i] = get<std::int16_t>(h + 40 + 2 * i, swap);
  if (dim[0] < 3 || dim[0] > 4) {
    throw Error(name + ": expected a 3D or 4D image, found " + std::to_string(dim[0]) +
                " dimensions");
  }
  for (int i = 1; i <= dim[0]; ++i) {
    if (dim[i] < 1)
      throw Error(name + ": dimension " + std::to_string(i) + " has size " +
                  std::to_string(dim[i]));
  }
  const int nt = dim[0] == 4 ? dim[4] : 1;
  const auto datatype = get<std::int16_t>(h + 70, swap);
  double pixdim[8];
  for (int i = 0; i < 8; ++i) pixdim[i] = get<float>(h + 76 + 4 * i, swap);
  const double vox_offset = get<float>(h + 108, swap);
  double slope = get<float>(h + 112, swap);
  const double inter = get<float>(h + 116, swap);
  const int xyzt = h[123];
  const auto qform_code = get<std::int16_t>(h + 252, swap);
  const auto sform_code = get<std::int16_t>(h + 254, swap);

  int bytes = 0;
  switch (datatype) {
    case 2:
    case 256:
      bytes = 1;
      break;  // uint8, int8
    case 4:
    case 512:
      bytes = 2;
      break;  // int16, uint16
    case 8:
    case 768:
    case 16:
      bytes = 4;
      break;  // int32, uint32, float32
    case 64:
      bytes = 8;
      break;  // float64
    default:
      throw Error(name + ": unsupported NIfTI datatype " + std::to_string(datatype));
  }
  if (!std::isfinite(slope) || slope == 0.0) slope = 1.0;

  // Geometry: voxel -> world affine A (3x4), in mm.
  const double to_mm = spatial_unit_to_mm(xyzt);
  Eigen::Matrix3d M;
  Eigen::Vector3d offset;
  if (sform_code > 0) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) M(r, c) = get<float>(h + 280 + 16 * r + 4 * c, swap);
      offset[r] = get<float>(h + 280 + 16 * r + 12, swap);
    }
  } else if (qform_code > 0) {
    const double b = get<float>(h + 256, swap), c = get<float>(h + 260, swap),
                 d = get<float>(h + 264, swap);
    const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
    Eigen::Matrix3d R;
    R << a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),
        2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b),
        2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b;
    const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
    M = R * Eigen::Vector3d(pixdim[1], pixdim[2], qfac * pixdim[3]).asDiagonal();
    offset = Eigen::Vector3d(get<float>(h + 268, swap), get<float>(h + 272, swap),
                             get<float>(h + 276, swap));
  } else {
    M = Eigen::Vector3d(pixdim[1], pixdim[2], pixdim[3]).asDiagonal();
    offset.setZero();
  }
  M *= to_mm;
  offset *= to_mm;
  ImageVolume geom;
  geom.size = {dim[1], dim[2], dim[3]};
  for (int c = 0; c < 3; ++c) {
    geom.spacing[c] = M.col(c).norm();
    if (!(geom.spacing[c] > 0.0) || !std::isfinite(geom.spacing[c])) {
      throw Error(name + ": voxel spacing along axis " + std::to_string(c) + " is zero or invalid");
    }
    geom.direction.col(c) = M.col(c) / geom.spacing[c];
  }
  geom.origin = offset;

  // Skip to the voxel data.
  if (!(vox_offset >= kHeaderSize && vox_offset < 9.0e18))
    throw Error(name + ": vox_offset " + std::to_string(vox_offset) + " is inside the header");
  const auto skip = static_cast<std::uint64_t>(vox_offset) - kHeaderSize;
  const size_t nvox = geom.num_voxels();
  // What the header claims against what the file can hold (uncompressed: its size; gzip: the
  // most its bytes can inflate to), before anything of that size is allocated.
  {
    const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
    const bool compressed = gzdirect(gz.f) == 0;
    const double claimed = static_cast<double>(kHeaderSize) + static_cast<double>(skip) +
                           static_cast<double>(nvox) * bytes * nt;
    const double holds = compressed ? static_cast<double>(raw::max_inflated_size(file_bytes))
                                    : static_cast<double>(file_bytes);
    if (ec || claimed > holds) {
      char text[64];
      std::snprintf(text, sizeof text, "%.0f", claimed);  // may exceed any integer type
      const std::string claims =
          "the header claims " + std::string(text) + " bytes of header and data";
      throw Error(name + (compressed ? ": " + claims + ", more than " + std::to_string(file_bytes) +
                                           " gzip-compressed bytes can hold (a corrupt header "
                                           "or a compression bomb)"
                                     : ": truncated voxel data (" + claims + ", the file has " +
                                           std::to_string(file_bytes) + ")"));
    }
  }
  for (std::uint64_t left = skip; left > 0;) {  // extensions: read past, not kept
    unsigned char discard[65536];
    const auto chunk = static_cast<unsigned>(std::min<std::uint64_t>(left, sizeof discard));
    if (gzread(gz.f, discard, chunk) != static_cast<int>(chunk))
      throw Error(name + ": truncated before the voxel data");
    left -= chunk;
  }
  std::vector<ImageVolume> out;
  std::vector<unsigned char> raw(nvox * bytes);
  for (int t = 0; t < nt; ++t) {
    size_t got = 0;
    while (got < raw.size()) {
      const unsigned chunk = static_cast<unsigned>(std::min<size_t>(raw.size() - got, 1u << 30));
      const int r = gzread(gz.f, raw.data() + got, chunk);
      if (r <= 0) break;
      got += static_cast<size_t>(r);
    }
    if (got != raw.size()) {
      throw Error(name + ": truncated voxel data (volume " + std::to_string(t) + ": expected " +
                  std::to_string(raw.size()) + " bytes, got " + std::to_string(got) + ")");
    }
    ImageVolume im = geom;
    im.time_s = nt > 1 ? t * pixdim[4] * time_unit_to_s(xyzt) : 0.0;
    im.data.resize(nvox);
    for (size_t i = 0; i < nvox; ++i) {
      const unsigned char* p = raw.data() + i * bytes;
      double v = 0.0;
      switch (datatype) {
        case 2:
          v = p[0];
          break;
        case 256:
          v = static_cast<std::int8_t>(p[0]);
          break;
        case 4:
          v = get<std::int16_t>(p, swap);
          break;
        case 512:
          v = get<std::uint16_t>(p, swap);
          break;
        case 8:
          v = get<std::int32_t>(p, swap);
          break;
        case 768:
          v = get<std::uint32_t>(p, swap);
          break;
        case 16:
          v = get<float>(p, swap);
          break;
        case 64:
          v = get<double>(p, swap);
          break;
      }
      im.data[i] = static_cast<float>(v * slope + inter);
    }
    out.push_back(std::move(im));
  }
  return out;
}

ImageVolume read_nifti(const std::filesystem::path& path) {
  std::vector<ImageVolume> v = read_nifti_series(path);
  if (v.size() != 1) {
    throw Error(path.string() + ": expected a 3D image, found " + std::to_string(v.size()) +
                " time points");
  }
  return std::move(v.front());
}

void write_nifti(const std::filesystem::path& path, const ImageVolume& im) {
  if (im.data.size() != im.num_voxels())
    throw Error(path.string() + ": image data size does not match its dimensions");
  for (int c = 0; c < 3; ++c) {
    if (im.size[c] < 1 || im.size[c] > 32767)
      throw Error(path.string() + ": image size out of NIfTI-1 range");
  }
  unsigned char h[kHeaderSize + 4] = {};
  put<std::int32_t>(h, kHeaderSize);
  const std::int16_t dim[8] = {3,
                               static_cast<std::int16_t>(im.size[0]),
                               static_cast<std::int16_t>(im.size[1]),
                               static_cast<std::int16_t>(im.size[2]),
                               1,
                               1,
                               1,
                               1};
  for (int i = 0; i < 8; ++i) put<std::int16_t>(h + 40 + 2 * i, dim[i]);
  put<std::int16_t>(h + 70, 16);  // float32
  put<std::int16_t>(h + 72, 32);
  Eigen::Matrix3d R = im.direction;
  float qfac = 1.0f;
  if (R.determinant() < 0) {
    R.col(2) *= -1.0;
    qfac = -1.0f;
  }
  const float pixdim[8] = {qfac,
                           static_cast<float>(im.spacing[0]),
                           static_cast<float>(im.spacing[1]),
                           static_cast<float>(im.spacing[2]),
                           1,
                           1,
                           1,
                           1};
  for (int i = 0; i < 8; ++i) put<float>(h + 76 + 4 * i, pixdim[i]);
  put<float>(h + 108, 352.0f);
  put<float>(h + 112, 1.0f);
  h[123] = 2 | 8;  // mm, s
  std::strncpy(reinterpret_cast<char*>(h + 148), "mvtwin", 79);
  put<std::int16_t>(h + 252, 1);
  put<std::int16_t>(h + 254, 1);
  const Eigen::Quaterniond q(R);
  const Eigen::Quaterniond qn = q.w() < 0 ? Eigen::Quaterniond(-q.coeffs()) : q;
  put<float>(h + 256, static_cast<float>(qn.x()));
  put<float>(h + 260, static_cast<float>(qn.y()));
  put<float>(h + 264, static_cast<float>(qn.z()));
  for (int r = 0; r < 3; ++r) put<float>(h + 268 + 4 * r, static_cast<float>(im.origin[r]));
  const Eigen::Matrix3d A = im.direction * im.spacing.asDiagonal();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) put<float>(h + 280 + 16 * r + 4 * c, static_cast<float>(A(r, c)));
    put<float>(h + 280 + 16 * r + 12, static_cast<float>(im.origin[r]));
  }
  std::memcpy(h + 344, "n+1", 4);
  const bool gzip = path.extension() == ".gz";
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    GzFile gz;
    gz.f = gzopen(tmp.c_str(), gzip ? "wb6" : "wbT");
    if (!gz.f) throw Error(path.string() + ": cannot open for writing");
    const size_t bytes = im.data.size() * sizeof(float);
    if (gzwrite(gz.f, h, kHeaderSize + 4) != kHeaderSize + 4 ||
        (bytes > 0 &&
         gzwrite(gz.f, im.data.data(), static_cast<unsigned>(bytes)) != static_cast<int>(bytes))) {
      throw Error(path.string() + ": write failed (disk full?)");
    }
    if (gzclose(gz.f) != Z_OK) {
      gz.f = nullptr;
      throw Error(path.string() + ": write failed on close");
    }
    gz.f = nullptr;
  });
}

}  // namespace mvtwin
