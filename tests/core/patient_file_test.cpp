#include "mvtwin/core/patient_file.h"

#include <hdf5.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

class PatientFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mvtwin_pf_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    patient_ = make_virtual_patient(11);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Replaces dataset `name` of an existing file by a float64 array of the given shape.
  static void replace_dataset(const fs::path& file, const char* name,
                              const std::vector<double>& data, const std::vector<hsize_t>& dims) {
    const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    H5Ldelete(f, name, H5P_DEFAULT);
    if (!data.empty()) {
      const hid_t s = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
      const hid_t d =
          H5Dcreate2(f, name, H5T_NATIVE_DOUBLE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, data.data());
      H5Dclose(d);
      H5Sclose(s);
    }
    H5Fclose(f);
  }

  static std::vector<double> read_all(const fs::path& file, const char* name,
                                      std::vector<hsize_t>* dims) {
    const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
    const hid_t s = H5Dget_space(d);
    dims->resize(H5Sget_simple_extent_ndims(s));
    H5Sget_simple_extent_dims(s, dims->data(), nullptr);
    std::vector<double> v(H5Sget_simple_extent_npoints(s));
    H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Sclose(s);
    H5Dclose(d);
    H5Fclose(f);
    return v;
  }

  // The error message of reading `file`, or "" if it read fine.
  static std::string read_error(const fs::path& file) {
    try {
      read_patient(file);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
  Patient patient_;
};

TEST_F(PatientFile, RoundTripKeepsEverything) {
  ImageVolume im;
  im.size = {4, 3, 2};
  im.spacing = {0.5, 0.75, 1.5};
  im.origin = {1, 2, 3};
  im.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (int i = 0; i < 24; ++i) im.data.push_back(static_cast<float>(i) * 0.5f);
  patient_.images.push_back(im);
  const fs::path p = dir_ / "p.h5";
  write_patient(p, patient_);
  const Patient q = read_patient(p);
  EXPECT_EQ(q.id, patient_.id);
  EXPECT_TRUE(q.synthetic);
  EXPECT_EQ(q.provenance.seed, 11u);
  EXPECT_EQ(q.provenance.command, patient_.provenance.command);
  const ValveSequence &a = patient_.sequence, &b = q.sequence;
  ASSERT_EQ(a.num_frames(), b.num_frames());
  EXPECT_EQ(a.end_diastole, b.end_diastole);
  EXPECT_EQ(a.first_closed, b.first_closed);
  for (int f = 0; f < a.num_frames(); ++f) {
    EXPECT_EQ(a.frames[f].time_s, b.frames[f].time_s);
    EXPECT_EQ(a.frames[f].annulus, b.frames[f].annulus);
    EXPECT_EQ(a.frames[f].landmark_observed, b.frames[f].landmark_observed);
    for (int l = 0; l < kNumLandmarks; ++l) {
      if (a.frames[f].landmark_observed[l]) {
        EXPECT_EQ(a.frames[f].landmarks[l], b.frames[f].landmarks[l]);
      }
    }
    ASSERT_EQ(a.frames[f].la_surface.has_value(), b.frames[f].la_surface.has_value());
    if (a.frames[f].la_surface) {
      EXPECT_EQ(a.frames[f].la_surface->points(), b.frames[f].la_surface->points());
    }
  }
  ASSERT_TRUE(q.truth);
  EXPECT_EQ(q.truth->pathology, patient_.truth->pathology);
  EXPECT_EQ(q.truth->parameters.restlength_factor, patient_.truth->parameters.restlength_factor);
  EXPECT_EQ(q.truth->parameters.peak_pressure_mpa, patient_.truth->parameters.peak_pressure_mpa);
  EXPECT_EQ(q.truth->pose, patient_.truth->pose);
  EXPECT_EQ(q.truth->anatomy, patient_.truth->anatomy);
  ASSERT_EQ(q.images.size(), 1u);
  EXPECT_EQ(q.images[0].data, im.data);
  EXPECT_EQ(q.images[0].size, im.size);
  EXPECT_TRUE(q.images[0].direction.isApprox(im.direction));
  EXPECT_TRUE(q.images[0].spacing.isApprox(im.spacing));
}

// Torn chordae are anatomy on the sequence: drawn for the ruptured-chordae pathology (on the
// posterior leaflet), kept by the file, converted from older files that held marginal chorda
// indices under /ground_truth, and refused when malformed.
TEST_F(PatientFile, ChordaeRupturesAreAnatomyAndOlderFilesConvert) {
  VirtualPatientOptions vo;
  vo.pathology = Pathology::kProlapseRupturedChordae;
  const Patient torn = make_virtual_patient(3, vo);
  ASSERT_EQ(torn.sequence.ruptured_chordae.size(), 1u);
  EXPECT_GE(torn.sequence.ruptured_chordae[0].s_begin, 0.5);  // posterior scallops
  EXPECT_TRUE(patient_.sequence.ruptured_chordae.empty() ||
              patient_.truth->pathology == Pathology::kProlapseRupturedChordae);

  Patient p = patient_;
  p.sequence.ruptured_chordae = {{0.6, 0.65}, {0.8, 0.9}};
  const fs::path f = dir_ / "torn.h5";
  write_patient(f, p);
  const Patient q = read_patient(f);
  ASSERT_EQ(q.sequence.ruptured_chordae.size(), 2u);
  EXPECT_EQ(q.sequence.ruptured_chordae[1].s_begin, 0.8);
  EXPECT_EQ(q.sequence.ruptured_chordae[1].s_end, 0.9);

  replace_dataset(f, "sequence/ruptured_chordae", {}, {});
  replace_dataset(f, "ground_truth/ruptured_marginal_chordae", {23, 24}, {2});
  const Patient old = read_patient(f);
  ASSERT_EQ(old.sequence.ruptured_chordae.size(), 2u);
  EXPECT_NEAR(old.sequence.ruptured_chordae[0].s_begin, 22.5 / 28, 1e-15);
  EXPECT_NEAR(old.sequence.ruptured_chordae[1].s_end, 24.5 / 28, 1e-15);

  replace_dataset(f, "ground_truth/ruptured_marginal_chordae", {}, {});
  replace_dataset(f, "sequence/ruptured_chordae", {0.7, 0.6}, {1, 2});
  try {
    read_patient(f);
    FAIL() << "a reversed rupture was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rupture"), std::string::npos) << e.what();
  }
}

// Marginal chordae lengths are anatomy on the sequence: recorded by the generator (by default), at
// the 28 insertion sites of Mansi et al. (taut in its estimate of the closed valve), interpolated
// linearly and periodically between sites, kept by the file, absent from older files (the model
// then starts from the end-diastolic distances), and refused when malformed.
TEST_F(PatientFile, MarginalChordaeLengthsAreAnatomyKeptByTheFile) {
  EXPECT_TRUE(make_virtual_patient(11, VirtualPatientOptions::before_closing_anatomy())
                  .sequence.marginal_chordae_lengths.empty());  // not by the generator before them
  const Patient with = make_virtual_patient(11);
  const std::vector<ChordaLength>& made = with.sequence.marginal_chordae_lengths;
  ASSERT_EQ(made.size(), 28u);
  for (size_t k = 0; k < made.size(); ++k) {
    EXPECT_NEAR(made[k].s, static_cast<double>(k) / 28, 1e-15);
    EXPECT_GT(made[k].length_mm, 5.0);
    EXPECT_LT(made[k].length_mm, 40.0);
  }

  ValveSequence seq = patient_.sequence;
  seq.marginal_chordae_lengths = {{0.1, 10.0}, {0.5, 20.0}, {0.9, 14.0}};
  EXPECT_NEAR(seq.marginal_chorda_length_at(0.1), 10.0, 1e-12);
  EXPECT_NEAR(seq.marginal_chorda_length_at(0.3), 15.0, 1e-12);
  EXPECT_NEAR(seq.marginal_chorda_length_at(0.7), 17.0, 1e-12);
  EXPECT_NEAR(seq.marginal_chorda_length_at(0.0), 12.0, 1e-12);   // across s = 0 ...
  EXPECT_NEAR(seq.marginal_chorda_length_at(0.95), 13.0, 1e-12);  // ... from 0.9 to 1.1
  EXPECT_NEAR(seq.marginal_chorda_length_at(1.05), 11.0, 1e-12);  // periodic
  seq.marginal_chordae_lengths.clear();
  EXPECT_TRUE(std::isnan(seq.marginal_chorda_length_at(0.3)));

  const fs::path f = dir_ / "lengths.h5";
  write_patient(f, with);
  const Patient q = read_patient(f);
  ASSERT_EQ(q.sequence.marginal_chordae_lengths.size(), made.size());
  for (size_t k = 0; k < made.size(); ++k) {
    EXPECT_EQ(q.sequence.marginal_chordae_lengths[k].s, made[k].s);
    EXPECT_EQ(q.sequence.marginal_chordae_lengths[k].length_mm, made[k].length_mm);
  }

  replace_dataset(f, "sequence/marginal_chordae_lengths", {}, {});
  EXPECT_TRUE(read_patient(f).sequence.marginal_chordae_lengths.empty());

  // A sequence detected from images keeps the known chordae (lengths and tears) unless it has
  // its own.
  ValveSequence detected = patient_.sequence;
  detected.ruptured_chordae.clear();
  detected.marginal_chordae_lengths.clear();
  ValveSequence known = with.sequence;
  known.ruptured_chordae = {{0.6, 0.65}};
  detected.keep_chordae_anatomy(known);
  ASSERT_EQ(detected.marginal_chordae_lengths.size(), made.size());
  EXPECT_EQ(detected.marginal_chordae_lengths[5].length_mm, made[5].length_mm);
  ASSERT_EQ(detected.ruptured_chordae.size(), 1u);
  EXPECT_EQ(detected.ruptured_chordae[0].s_begin, 0.6);
  detected.marginal_chordae_lengths = {{0.5, 12.0}};
  detected.keep_chordae_anatomy(known);
  ASSERT_EQ(detected.marginal_chordae_lengths.size(), 1u);
  EXPECT_EQ(detected.marginal_chordae_lengths[0].length_mm, 12.0);

  for (const std::vector<double>& bad :
       {std::vector<double>{0.2, 12.0, 0.1, 13.0}, std::vector<double>{0.2, 0.0, 0.4, 13.0}}) {
    replace_dataset(f, "sequence/marginal_chordae_lengths", bad, {2, 2});
    try {
      read_patient(f);
      FAIL() << "malformed chordae lengths were accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("marginal chord"), std::string::npos) << e.what();
    }
  }
}

TEST_F(PatientFile, DetectedSequenceIsKeptBesideTheStoredOne) {
  const fs::path p = dir_ / "d.h5";
  write_patient(p, patient_);
  EXPECT_FALSE(read_patient(p).detected) << "no detection until one is written";
  // A detection that differs from the stored sequence: both must come back, unmixed.
  ValveSequence det = patient_.sequence.resampled(16, 6);
  for (auto& f : det.frames) {
    if (f.la_surface) f.la_surface->points().array() += 1.0;
    f.annulus = f.la_surface ? Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>(
                                   f.la_surface->points().topRows(16))
                             : f.annulus;
  }
  patient_.detected = det;
  patient_.detected_by = "model m.yml.gz";
  write_patient(p, patient_);
  const Patient q = read_patient(p);
  ASSERT_TRUE(q.detected);
  EXPECT_EQ(q.detected_by, "model m.yml.gz");
  EXPECT_EQ(q.detected->ures, 16);
  EXPECT_EQ(q.sequence.ures, patient_.sequence.ures) << "the stored sequence is untouched";
  for (int f = 0; f < det.num_frames(); ++f) {
    if (!det.frames[f].la_surface) continue;
    EXPECT_EQ(q.detected->frames[f].la_surface->points(), det.frames[f].la_surface->points());
    EXPECT_EQ(q.sequence.frames[f].la_surface->points(),
              patient_.sequence.frames[f].la_surface->points());
  }
  // A bad detection is refused before anything is written.
  const auto size = fs::file_size(p);
  patient_.detected->frames[0].annulus(0, 0) = std::nan("");
  EXPECT_THROW(write_patient(p, patient_), Error);
  EXPECT_EQ(fs::file_size(p), size);
  EXPECT_TRUE(read_patient(p).detected);
}

TEST_F(PatientFile, ClearErrorsForBadFiles) {
  EXPECT_NE(read_error(dir_ / "absent.h5").find("no such file"), std::string::npos);
  { std::ofstream(dir_ / "text.h5") << "this is not HDF5\n"; }
  EXPECT_NE(read_error(dir_ / "text.h5").find("not an HDF5 file"), std::string::npos);
  // A truncated copy of a good file.
  const fs::path good = dir_ / "good.h5";
  write_patient(good, patient_);
  {
    std::ifstream in(good, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream out(dir_ / "trunc.h5", std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  const std::string trunc = read_error(dir_ / "trunc.h5");
  EXPECT_NE(trunc.find("trunc.h5"), std::string::npos) << trunc;
  EXPECT_FALSE(trunc.empty());
}

TEST_F(PatientFile, ErrorsNameTheDatasetAndProblem) {
  const fs::path p = dir_ / "p.h5";
  std::vector<hsize_t> dims;

  write_patient(p, patient_);
  replace_dataset(p, "/sequence/annulus", {}, {});
  std::string e = read_error(p);
  EXPECT_NE(e.find("/sequence/annulus: dataset is missing"), std::string::npos) << e;

  write_patient(p, patient_);
  auto lm = read_all(p, "/sequence/landmarks", &dims);
  replace_dataset(p, "/sequence/landmarks", std::vector<double>(dims[0] * 8 * 3, 0.0),
                  {dims[0], 8, 3});
  e = read_error(p);
  EXPECT_NE(e.find("/sequence/landmarks: expected shape (F, 9, 3)"), std::string::npos) << e;

  write_patient(p, patient_);
  auto surf = read_all(p, "/sequence/la_surface", &dims);
  surf[5] = std::nan("");  // frame 0 is observed
  replace_dataset(p, "/sequence/la_surface", surf, dims);
  e = read_error(p);
  EXPECT_NE(e.find("la_surface: frame 0, point (u=1, v=0) is NaN"), std::string::npos) << e;

  write_patient(p, patient_);
  auto t = read_all(p, "/sequence/time", &dims);
  std::swap(t[2], t[3]);
  replace_dataset(p, "/sequence/time", t, dims);
  e = read_error(p);
  EXPECT_NE(e.find("times are not strictly increasing"), std::string::npos) << e;
}

// A dataset whose dataspace claims more elements than its bytes in the file can hold (here a
// chunked dataset of the right shape with no chunk written: 0 bytes stored) is refused before
// the reader allocates for it (the guard the fuzzers' huge-dataspace inputs led to).
TEST_F(PatientFile, DatasetsClaimingMoreThanTheirStoredBytesAreRefused) {
  const fs::path p = dir_ / "p.h5";
  write_patient(p, patient_);
  std::vector<hsize_t> dims;
  read_all(p, "/sequence/la_surface", &dims);
  {
    const hid_t f = H5Fopen(p.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    H5Ldelete(f, "/sequence/la_surface", H5P_DEFAULT);
    const hid_t s = H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr);
    const hid_t plist = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(plist, static_cast<int>(dims.size()), dims.data());
    const hid_t d = H5Dcreate2(f, "/sequence/la_surface", H5T_NATIVE_DOUBLE, s, H5P_DEFAULT, plist,
                               H5P_DEFAULT);
    ASSERT_GE(d, 0);
    H5Dclose(d);
    H5Pclose(plist);
    H5Sclose(s);
    H5Fclose(f);
  }
  const std::string e = read_error(p);
  EXPECT_NE(e.find("/sequence/la_surface: the dataset claims"), std::string::npos) << e;
  EXPECT_NE(e.find("0 bytes in the file"), std::string::npos) << e;
}

TEST_F(PatientFile, FailedWriteLeavesTheOldFileUntouched) {
  const fs::path p = dir_ / "p.h5";
  write_patient(p, patient_);
  const auto size_before = fs::file_size(p);
  Patient bad = patient_;
  bad.sequence.frames[1].time_s = bad.sequence.frames[0].time_s;  // invalid
  EXPECT_THROW(write_patient(p, bad), Error);
  EXPECT_EQ(fs::file_size(p), size_before);
  EXPECT_NO_THROW(read_patient(p));
  // No temporary files left behind.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) files += entry.is_regular_file();
  EXPECT_EQ(files, 1);
  // A missing directory is named.
  try {
    write_patient(dir_ / "nope" / "p.h5", patient_);
    FAIL() << "expected an error";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("does not exist"), std::string::npos);
  }
}

TEST_F(PatientFile, SyntheticIsAlwaysLabelled) {
  Patient p = patient_;
  p.synthetic = false;  // a virtual truth on a "real" patient is refused
  EXPECT_THROW(write_patient(dir_ / "x.h5", p), Error);
  const fs::path f = dir_ / "v.h5";
  write_patient(f, patient_);
  const hid_t h = H5Fopen(f.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t a = H5Aopen(h, "data_origin", H5P_DEFAULT);
  const hid_t type = H5Aget_type(a);
  // A fixed-length string (docs/fuzzing.md: text attributes stay under the object header's
  // checksum), read as any HDF5 reader would.
  ASSERT_EQ(H5Tis_variable_str(type), 0);
  std::string s(H5Tget_size(type), '\0');
  ASSERT_GE(H5Aread(a, type, s.data()), 0);
  EXPECT_NE(s.find("SYNTHETIC"), std::string::npos) << s;
  H5Tclose(type);
  H5Aclose(a);
  H5Fclose(h);
}

}  // namespace
}  // namespace mvtwin
