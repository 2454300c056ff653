#include "mvtwin/studies/en_face.h"

#include <filesystem>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "mvtwin/core/closure_measures.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::studies {
namespace {

namespace fs = std::filesystem;

/// Pixels of the open orifice's colour.
int open_pixels(const cv::Mat& img) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      n += p[0] == kEnFaceOpenBgr[0] && p[1] == kEnFaceOpenBgr[1] && p[2] == kEnFaceOpenBgr[2];
    }
  return n;
}

TEST(EnFace, TheOpenAreaDrawnIsTheOrificeSeenAlongTheAnnulusNormal) {
  // The picture's dark red, counted and scaled back to mm^2, is the line-of-sight orifice
  // (core/closure_measures.h) of the same surface: an open frame and the end-diastolic one.
  const Patient p = make_virtual_patient(1);
  const fs::path dir = fs::temp_directory_path() / "mvtwin_en_face_test";
  fs::create_directories(dir);
  for (int f : {0, p.sequence.end_diastole}) {  // open; nearly closed
    SCOPED_TRACE(f);
    const ValveFrame& frame = p.sequence.frames[static_cast<size_t>(f)];
    ASSERT_TRUE(frame.la_surface.has_value());
    EnFaceView v;
    v.title = "frame " + std::to_string(f);
    v.clips = {0.5};
    const fs::path png = dir / ("frame" + std::to_string(f) + ".png");
    const double scale = write_en_face_png(png, *frame.la_surface, v);
    const cv::Mat img = cv::imread(png.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty());
    const double drawn = open_pixels(img) / (scale * scale);
    const double measured = measure_closure(frame).orifice_area_mm2;
    std::printf("frame %d: drawn %.1f mm^2, measured %.1f mm^2\n", f, drawn, measured);
    EXPECT_NEAR(drawn, measured, 0.1 * measured + 3.0);
    // The anterior leaflet (blue: B > R) at the top, the posterior (R > B) at the bottom.
    int blue_top = 0, blue_bottom = 0;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const cv::Vec3b q = img.at<cv::Vec3b>(y, x);
        if (q[0] > q[2] + 60) (y < img.rows / 2 ? blue_top : blue_bottom) += 1;
      }
    EXPECT_GT(blue_top, 3 * blue_bottom);
  }
  EXPECT_GT(measure_closure(p.sequence.frames[0]).orifice_area_mm2, 100.0) << "frame 0 is open";
  // A surface without area is refused, naming the file.
  LeafletGrid flat = *p.sequence.frames[0].la_surface;
  flat.points().setZero();
  try {
    write_en_face_png(dir / "flat.png", flat, {});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("flat.png"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(dir / "flat.png"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mvtwin::studies
