#include "mvtwin/core/nifti.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

class Nifti : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mvtwin_nii_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    im_.size = {7, 5, 4};
    im_.spacing = {0.5, 0.8, 1.25};
    im_.origin = {-10, 20.5, 3};
    im_.direction =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
    for (size_t i = 0; i < im_.num_voxels(); ++i)
      im_.data.push_back(static_cast<float>(i % 11) - 3.5f);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string error_of(const fs::path& p) {
    try {
      read_nifti(p);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
  ImageVolume im_;
};

TEST_F(Nifti, RoundTripKeepsVoxelsAndGeometry) {
  for (const char* name : {"a.nii", "a.nii.gz"}) {
    write_nifti(dir_ / name, im_);
    const ImageVolume r = read_nifti(dir_ / name);
    EXPECT_EQ(r.size, im_.size);
    EXPECT_EQ(r.data, im_.data);
    EXPECT_LT((r.spacing - im_.spacing).norm(), 1e-5);
    EXPECT_LT((r.origin - im_.origin).norm(), 1e-4);
    EXPECT_LT((r.direction - im_.direction).norm(), 1e-5);
    // voxel -> world agrees
    EXPECT_LT((r.position(3, 2, 1) - im_.position(3, 2, 1)).norm(), 1e-4);
  }
  EXPECT_LT(fs::file_size(dir_ / "a.nii.gz"), fs::file_size(dir_ / "a.nii"));
}

TEST_F(Nifti, AgreesWithNibabel) {
  if (std::system("/usr/bin/python3 -c 'import nibabel' > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "python3-nibabel absent: cross-check skipped";
  }
  write_nifti(dir_ / "b.nii.gz", im_);
  const fs::path out = dir_ / "nib.txt";
  const std::string cmd =
      "/usr/bin/python3 -c \"import nibabel as nb\ni=nb.load('" + (dir_ / "b.nii.gz").string() +
      "')\nimport numpy as np\nx=i.affine@np.array([3,2,1,1])\nd=i.get_fdata()\n"
      "print('%.4f %.4f %.4f %.2f' % (x[0],x[1],x[2],d[3,2,1]))\" > " +
      out.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream f(out);
  double x, y, z, v;
  f >> x >> y >> z >> v;
  const Eigen::Vector3d p = im_.position(3, 2, 1);
  EXPECT_NEAR(x, p.x(), 1e-3);
  EXPECT_NEAR(y, p.y(), 1e-3);
  EXPECT_NEAR(z, p.z(), 1e-3);
  EXPECT_NEAR(v, im_.at(3, 2, 1), 1e-6);
}

TEST_F(Nifti, BadFilesGetClearErrors) {
  EXPECT_NE(error_of(dir_ / "none.nii").find("no such file"), std::string::npos);
  { std::ofstream(dir_ / "text.nii") << "hello, not an image"; }
  EXPECT_NE(error_of(dir_ / "text.nii").find("too short for a NIfTI header"), std::string::npos);
  {
    std::ofstream f(dir_ / "junk.nii", std::ios::binary);
    for (int i = 0; i < 400; ++i) f.put(static_cast<char>(i));
  }
  EXPECT_NE(error_of(dir_ / "junk.nii").find("not a NIfTI-1 file"), std::string::npos);
  write_nifti(dir_ / "c.nii", im_);
  fs::resize_file(dir_ / "c.nii", fs::file_size(dir_ / "c.nii") - 10);
  EXPECT_NE(error_of(dir_ / "c.nii").find("truncated voxel data"), std::string::npos);
}

TEST_F(Nifti, RealLabelMapFromSharedData) {
  const fs::path p = fs::path(MVTWIN_SHARED_DATA_DIR) / "mvtool-008" / "008_gt.nii.gz";
  if (!fs::exists(p))
    GTEST_SKIP() << "../shared/data absent (a user's clone has no ../shared): skipped";
  const ImageVolume im = read_nifti(p);
  EXPECT_EQ(im.size, (std::array<int, 3>{173, 188, 83}));
  EXPECT_NEAR(im.spacing.x(), 0.5, 1e-6);
  int counts[4] = {0, 0, 0, 0};
  for (float v : im.data) counts[static_cast<int>(v)]++;
  // Voxel counts from the data set's README.
  EXPECT_EQ(counts[1], 7765);
  EXPECT_EQ(counts[2], 22089);
  EXPECT_EQ(counts[3], 15773);
}

}  // namespace
}  // namespace mvtwin
