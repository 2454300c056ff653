#include "mvtwin/detection/shape_model.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mvtwin/core/error.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::detection {
namespace {

double mean_point_error(const Points3& a, const Points3& b) {
  return (a - b).rowwise().norm().mean();
}

TEST(Similarity, RecoversAKnownTransformAndInverts) {
  Points3 P(5, 3);
  P << 0, 0, 0, 10, 0, 0, 0, 7, 0, 0, 0, 4, 3, 2, 1;
  Similarity s;
  s.scale = 1.7;
  s.R = Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  s.t = {5, -3, 12};
  Points3 Q(5, 3);
  for (int i = 0; i < 5; ++i) Q.row(i) = s.apply(P.row(i).transpose()).transpose();
  const Similarity f = fit_similarity(P, Q);
  EXPECT_NEAR(f.scale, 1.7, 1e-10);
  EXPECT_LT((f.R - s.R).norm(), 1e-10);
  EXPECT_LT((f.t - s.t).norm(), 1e-9);
  const Eigen::Vector3d x(1, 2, 3);
  EXPECT_LT((f.inverse().apply(f.apply(x)) - x).norm(), 1e-10);
  EXPECT_THROW(fit_similarity(P.topRows(2), Q.topRows(2)), Error);
}

TEST(ShapeModel, HeldOutValvesAreCloserThanTheMeanShapeBaseline) {
  // Train on the open frames of 16 virtual patients, test on 4 others.
  std::vector<Patient> train, test;
  for (std::uint64_t s = 1; s <= 16; ++s) train.push_back(make_virtual_patient(s));
  for (std::uint64_t s = 501; s <= 504; ++s) test.push_back(make_virtual_patient(s));
  std::vector<const ValveFrame*> frames;
  for (const Patient& p : train)
    for (const ValveFrame& f : p.sequence.frames) frames.push_back(&f);
  const ShapeModel m = ShapeModel::train(frames, 0.98);
  ASSERT_GT(m.modes(), 2);
  // A training shape is reproduced by the model almost exactly.
  {
    const ValveFrame& f = *frames.front();
    const Points3 L = placing_landmarks(f);
    const Points3 r = m.constrain(f.la_surface->points(), m.placement(L), 10.0);
    EXPECT_LT(mean_point_error(r, f.la_surface->points()), 0.5);
  }
  double baseline = 0, model = 0, few = 0;
  int n = 0;
  for (const Patient& p : test) {
    for (const ValveFrame& f : p.sequence.frames) {
      if (!f.la_surface) continue;
      const LeafletGrid truth = f.la_surface->resampled(m.ures(), m.vres());
      const Points3 L = placing_landmarks(f);
      baseline += mean_point_error(m.place_mean(L), truth.points());
      model += mean_point_error(m.constrain(truth.points(), m.placement(L)), truth.points());
      few += mean_point_error(m.constrain(truth.points(), m.placement(L), 3.0, 2), truth.points());
      ++n;
    }
  }
  ASSERT_GT(n, 0);
  baseline /= n;
  model /= n;
  few /= n;
  RecordProperty("model_mm", std::to_string(model));
  RecordProperty("two_modes_mm", std::to_string(few));
  RecordProperty("mean_shape_mm", std::to_string(baseline));
  RecordProperty("modes", std::to_string(m.modes()));
  EXPECT_LT(model, few);
  EXPECT_LT(few, baseline);
  EXPECT_LT(model, 0.6 * baseline) << "model " << model << " mm, mean shape " << baseline << " mm";
  // Model files: a round trip keeps everything.
  const ShapeModel back = ShapeModel::deserialize(m.serialize());
  EXPECT_EQ(back.modes(), m.modes());
  EXPECT_EQ(back.basis(), m.basis());
  EXPECT_EQ(back.mean(), m.mean());
  std::vector<double> bad = m.serialize();
  bad.pop_back();
  EXPECT_THROW(ShapeModel::deserialize(bad), Error);
  EXPECT_THROW(ShapeModel::train({frames[0], frames[1]}), Error);
}

}  // namespace
}  // namespace mvtwin::detection
