#include "mvtwin/core/simulation_file.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "../support/sample_records.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

SimulationRecord sample_record() { return test_support::sample_simulation_record(); }

TEST(SimulationFile, RoundTrip) {
  const fs::path f =
      fs::temp_directory_path() / ("mvtwin_sim_" + std::to_string(::getpid()) + ".h5");
  const SimulationRecord a = sample_record();
  write_simulation_file(f, a);
  EXPECT_EQ(mvtwin_file_format(f), "mvtwin-simulation");
  const SimulationRecord b = read_simulation_file(f);
  EXPECT_EQ(b.patient_id, a.patient_id);
  EXPECT_TRUE(b.synthetic);
  EXPECT_EQ(b.provenance.seed, 12u);
  EXPECT_EQ(b.options, a.options);
  EXPECT_EQ(b.status, "converged");
  EXPECT_DOUBLE_EQ(b.parameters.peak_pressure_mpa, 0.0123);
  EXPECT_DOUBLE_EQ(b.parameters.restlength_factor[2], 1.234);
  EXPECT_EQ(b.orifice_area_mm2, a.orifice_area_mm2);
  ASSERT_EQ(b.la_surface.size(), 3u);
  EXPECT_EQ(b.la_surface[2].points(), a.la_surface[2].points());
  EXPECT_EQ(b.final_positions, a.final_positions);
  EXPECT_EQ(b.mesh.T, a.mesh.T);
  EXPECT_DOUBLE_EQ(b.element_stress_mpa[0], 0.05);
  ASSERT_EQ(b.summary.size(), 2u);
  EXPECT_EQ(b.summary[0].first, "steps");
  // The regurgitant orifice and the surface it was measured on, every field.
  ASSERT_TRUE(a.orifice && b.orifice);
  const RegurgitantOrifice &x = *a.orifice, &y = *b.orifice;
  EXPECT_GT(x.aroa_mm2, 0.0);
  EXPECT_EQ(y.aroa_mm2, x.aroa_mm2);
  EXPECT_EQ(y.eroa_mm2, x.eroa_mm2);
  EXPECT_EQ(y.grade, x.grade);
  EXPECT_EQ(y.options.seal_mm, x.options.seal_mm);
  EXPECT_EQ(y.coaptation_length_mm, x.coaptation_length_mm);
  EXPECT_EQ(std::isnan(y.coaptation_depth_mm), std::isnan(x.coaptation_depth_mm));
  ASSERT_EQ(y.openings.size(), x.openings.size());
  for (size_t i = 0; i < x.openings.size(); ++i) {
    EXPECT_EQ(y.openings[i].area_mm2, x.openings[i].area_mm2);
    EXPECT_EQ(y.openings[i].begin, x.openings[i].begin);
    EXPECT_EQ(y.openings[i].max_gap_mm, x.openings[i].max_gap_mm);
  }
  ASSERT_EQ(y.columns.size(), x.columns.size());
  EXPECT_EQ(y.columns[7].b, x.columns[7].b);
  EXPECT_EQ(y.columns[7].anterior, x.columns[7].anterior);
  EXPECT_EQ(b.orifice_surface.points(), a.orifice_surface.points());
  EXPECT_EQ(b.orifice_lv_surface.points(), a.orifice_lv_surface.points());
  EXPECT_TRUE(b.static_residual_n.empty()) << "no static solve, no group";
  // Without one (a failed simulation), no group and none read back.
  SimulationRecord c = a;
  c.orifice.reset();
  write_simulation_file(f, c);
  EXPECT_FALSE(read_simulation_file(f).orifice.has_value());
  // The static solve's residual history and failure, read back as written.
  c.static_residual_n = {0.86, 0.072, 4.7e-7};
  c.static_failure = "stalled";
  write_simulation_file(f, c);
  const SimulationRecord d = read_simulation_file(f);
  EXPECT_EQ(d.static_residual_n, c.static_residual_n);
  EXPECT_EQ(d.static_failure, "stalled");
  fs::remove(f);
}

TEST(SimulationFile, BadFilesAreNamed) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_simbad_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // A patient file is not a simulation file.
  write_patient(dir / "p.h5", make_virtual_patient(13));
  try {
    read_simulation_file(dir / "p.h5");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not an mvtwin simulation file"), std::string::npos);
  }
  std::ofstream(dir / "junk.h5") << "not hdf5";
  EXPECT_THROW(read_simulation_file(dir / "junk.h5"), Error);
  EXPECT_THROW(read_simulation_file(dir / "missing.h5"), Error);
  // Inconsistent records are refused and nothing is left behind.
  SimulationRecord r = sample_record();
  r.orifice_area_mm2.pop_back();
  EXPECT_THROW(write_simulation_file(dir / "bad.h5", r), Error);
  EXPECT_FALSE(fs::exists(dir / "bad.h5"));
  fs::remove_all(dir);
}

std::string file_bytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
void put_bytes(const fs::path& f, const std::string& b) {
  std::ofstream(f, std::ios::binary | std::ios::trunc) << b;
}

// Result files are written in HDF5's checksummed format (superblock version 3, version-2
// object headers, links and attributes kept in the headers), so damaged metadata is refused by
// libhdf5 instead of decoded (issue 15, docs/fuzzing.md). Every byte of the superblock and of
// the root group's object header (its attributes and links) is flipped in turn: each damaged
// file must be refused with mvtwin::Error. Then 600 bytes spread over the whole file: each must
// read (raw data or padding) or give mvtwin::Error; a crash or another exception fails the test
// (and the ASan flavour catches memory errors).
TEST(SimulationFile, DamagedMetadataIsRefusedByItsChecksum) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_simsum_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path f = dir / "s.h5";
  write_simulation_file(f, sample_record());
  const std::string good = file_bytes(f);
  auto u = [&](std::size_t at, int n) {
    std::uint64_t v = 0;
    for (int k = n - 1; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(good.at(at + k));
    return v;
  };
  ASSERT_EQ(u(8, 1), 3u) << "superblock version (3: checksummed, HDF5 1.10)";
  // Superblock v3: signature 8, version, offset and length sizes, flags, four addresses
  // (base, extension, end of file, root object header), checksum: 48 bytes.
  const std::size_t root = u(36, 8);
  ASSERT_EQ(good.substr(root, 4), "OHDR") << "root object header (version 2)";
  const unsigned flags = static_cast<unsigned char>(good[root + 5]);
  std::size_t at = root + 6 + ((flags & 0x20) ? 16 : 0) + ((flags & 0x10) ? 4 : 0);
  const int width = 1 << (flags & 3);
  const std::size_t end = at + width + u(at, width) + 4;  // chunk 0 and its checksum
  ASSERT_LT(end, good.size());
  ASSERT_GT(end - root, 200u) << "the root's attributes are not in its header";
  std::vector<std::size_t> metadata;
  for (std::size_t i = 0; i < 48; ++i) metadata.push_back(i);
  for (std::size_t i = root; i < end; ++i) metadata.push_back(i);
  auto damaged_read = [&](std::size_t i) {
    std::string bad = good;
    bad[i] = static_cast<char>(bad[i] ^ 0x5a);
    put_bytes(f, bad);
    try {
      read_simulation_file(f);
      return true;
    } catch (const Error&) {
      return false;
    }
  };
  int read = 0;
  for (std::size_t i : metadata) {
    const bool ok = damaged_read(i);
    read += ok;
    EXPECT_FALSE(ok) << "byte " << i << " of the metadata flipped and the file still read";
  }
  EXPECT_EQ(read, 0) << "of " << metadata.size() << " metadata bytes flipped";
  const std::size_t stride = std::max<std::size_t>(1, good.size() / 600) | 1;
  for (std::size_t i = 0; i < good.size(); i += stride) damaged_read(i);  // only Error, no crash
  fs::remove_all(dir);
}

// Variable-length strings are decoded from the file's global heap by mvtwin, each length
// checked against its heap object: a heap object claiming more bytes than its heap holds is
// refused by name (libhdf5 1.10 copied it unchecked: tests/fuzz/regressions/).
TEST(SimulationFile, StringsClaimingMoreThanTheirHeapHoldsAreRefused) {
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_simheap_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path f = dir / "s.h5";
  write_simulation_file(f, sample_record());
  std::string b = file_bytes(f);
  const std::size_t heap = b.find("GCOL");
  ASSERT_NE(heap, std::string::npos) << "no global heap: the strings are not variable-length?";
  // Collection header: "GCOL", version, 3 reserved, size (8); then the first object: index (2),
  // reference count (2), reserved (4), size (8).
  const std::size_t object_size = heap + 16 + 8;
  ASSERT_EQ(static_cast<unsigned char>(b[heap + 16]), 1u) << "first heap object's index";
  for (int k = 0; k < 8; ++k) b[object_size + k] = static_cast<char>(k < 4 ? 0xff : 0x00);
  put_bytes(f, b);
  try {
    read_simulation_file(f);
    FAIL() << "a heap object of 4 GB was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("global heap object runs past its heap"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// Files written before the checksummed format (superblock version 0, variable-length
// attributes and strings in a global heap) still read: a study table committed with the docs.
TEST(SimulationFile, FilesInTheEarlierFormatStillRead) {
  const fs::path old = fs::path(MVTWIN_SOURCE_DIR) / "docs/studies/robustness/study.h5";
  ASSERT_TRUE(fs::exists(old)) << old;
  ASSERT_EQ(static_cast<int>(file_bytes(old)[8]), 0) << "no longer a file of the earlier format";
  const TableFile t = read_table_file(old);
  EXPECT_EQ(t.format.rfind("mvtwin-", 0), 0u) << t.format;
  ASSERT_FALSE(t.columns.empty());
  bool strings = false;
  for (const TableColumn& c : t.columns) {
    EXPECT_GT(c.size(), 0u) << c.name;
    if (c.is_strings()) {
      strings = true;
      for (const std::string& v : c.strings) EXPECT_EQ(v.find('\0'), std::string::npos);
    }
    if (c.name == "outcome") {  // decoded text, not just bytes: every value is an outcome
      ASSERT_EQ(c.strings.size(), 200u);
      for (const std::string& v : c.strings)
        EXPECT_TRUE(v == "converged" || v == "clean_failure") << v;
    }
  }
  EXPECT_TRUE(strings) << "no string column to read";
  bool version = false;
  for (const auto& [k, v] : t.attributes)
    version |= k == "mvtwin_version" && v.rfind("0.1", 0) == 0;
  EXPECT_TRUE(version);
}

}  // namespace
}  // namespace mvtwin
