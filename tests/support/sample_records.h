#pragma once
// Small, complete result records for the tests and the fuzzers' seed corpora
// (tests/fuzz/make_seeds.cpp): every field set, some to NaN where the format allows it.
#include <cmath>

#include <Eigen/Core>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/regurgitant_orifice.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/virtual_patient.h"

namespace mvtwin::test_support {

/// A simulation record of virtual patient 12: three samples, a one-tetrahedron mesh.
inline SimulationRecord sample_simulation_record() {
  const Patient p = make_virtual_patient(12);
  SimulationRecord r;
  r.patient_id = p.id;
  r.patient_file = "p.h5";
  r.synthetic = true;
  r.provenance.command = "test";
  r.provenance.seed = 12;
  r.options = {{"dt", "0.01"}, {"contact", "on"}};
  r.parameters.peak_pressure_mpa = 0.0123;
  r.parameters.restlength_factor[2] = 1.234;
  r.status = "converged";
  r.summary = {{"steps", 42}, {"wall_s", 1.5}};
  for (int s = 0; s < 3; ++s) {
    r.time_s.push_back(0.1 * s);
    r.observed_time_s.push_back(0.5 + 0.01 * s);
    r.anterior_tip_mm.push_back(-10 + s);
    r.posterior_tip_mm.push_back(-8 + s);
    r.orifice_area_mm2.push_back(200 - 90 * s);
    r.annulus_area_mm2.push_back(700);
    r.la_surface.push_back(*p.sequence.frames[s].la_surface);
  }
  r.mesh.V.resize(4, 3);
  r.mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  r.mesh.T.resize(1, 4);
  r.mesh.T << 0, 1, 2, 3;
  r.mesh.tag.resize(1);
  r.mesh.tag << 1;
  r.mesh.fibre.resize(1, 3);
  r.mesh.fibre << 1, 0, 0;
  r.final_positions = r.mesh.V * 1.1;
  r.element_strain = Eigen::VectorXd::Constant(1, 0.1);
  r.element_stress_mpa = Eigen::VectorXd::Constant(1, 0.05);
  // The orifice measured on the last surface (an open frame: large openings).
  r.orifice_surface = r.la_surface.back();
  r.orifice_lv_surface = r.orifice_surface;
  r.orifice_lv_surface.points().col(2).array() -= 1.0;  // a stand-in, 1 mm below
  r.orifice = measure_regurgitant_orifice(r.orifice_surface, {}, &r.orifice_lv_surface);
  return r;
}

/// A calibration record of two fitted parameters with a three-row history.
inline CalibrationRecord sample_calibration_record() {
  CalibrationRecord r;
  r.patient_id = "virtual-3";
  r.patient_file = "p.h5";
  r.synthetic = true;
  r.provenance.command = "test";
  r.provenance.seed = 3;
  r.options = {{"ures", "20"}, {"fit_method", "bobyqa"}};
  r.method = "bobyqa";
  r.termination = "step tolerance reached";
  r.names = {"restlength_factor_a", "peak_pressure"};
  r.units = {"1", "mmHg"};
  r.lower = Eigen::Vector2d(0.7, 60);
  r.upper = Eigen::Vector2d(1.6, 200);
  r.start = Eigen::Vector2d(1.0, 120);
  r.fitted = Eigen::Vector2d(1.12, 131.5);
  r.sd = Eigen::Vector2d(0.01, std::nan(""));
  r.truth = Eigen::Vector2d(1.1, 130);
  r.identified = {1, 0};
  r.covariance = Eigen::Matrix2d{{1e-4, 2e-3}, {2e-3, 4.0}};
  r.correlation = Eigen::Matrix2d{{1, 0.1}, {0.1, 1}};
  r.noise_mm = 0.5;
  r.parameters.restlength_factor[0] = 1.12;
  r.error_before_mm = 1.5;
  r.error_after_mm = 0.6;
  r.simulations = 3;
  r.failed_simulations = 1;
  r.cache_hits = 2;
  r.wall_s = 12.5;
  r.history_simulation = {1, 2, 3};
  r.history_error_mm = {1.5, std::nan(""), 0.6};
  r.history_best_mm = {1.5, 1.5, 0.6};
  r.history_x = Eigen::MatrixXd{{1.0, 120}, {1.3, 150}, {1.12, 131.5}};
  return r;
}

}  // namespace mvtwin::test_support
