// Writes the fuzzers' seed corpora: small valid files of every format, made by mvtwin's own
// writers (so they follow the formats as they change) plus a few written by hand where mvtwin
// writes no such file (a 3D Slicer segmentation, .fcsv, a detector model's header).
//   mvtwin_fuzz_seeds DIR   ->   DIR/<harness>/<seed files>
// Harnesses that read several formats take a first byte choosing the ending (fuzz_input.h).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "../support/sample_records.h"
#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/image_io.h"
#include "mvtwin/core/markups.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"
#include "mvtwin/core/surface_mesh_io.h"
#include "mvtwin/core/table_file.h"
#include "mvtwin/core/virtual_patient.h"

namespace fs = std::filesystem;
using namespace mvtwin;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void spit(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << bytes;
}
// A file written under a scratch name, stored with the harness's selector byte in front.
void with_selector(const fs::path& written, char selector, const fs::path& seed) {
  spit(seed, std::string(1, selector) + slurp(written));
  fs::remove(written);
}

ImageVolume volume(int nx, int ny, int nz, double t) {
  ImageVolume v;
  v.size = {nx, ny, nz};
  v.spacing = {0.8, 0.9, 1.1};
  v.origin = {-3.0, 2.0, 5.0};
  v.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  v.time_s = t;
  for (std::size_t i = 0; i < v.num_voxels(); ++i) v.data.push_back(static_cast<float>(i % 7));
  return v;
}

void images(const fs::path& dir) {
  fs::create_directories(dir / "fuzz_nifti");
  fs::create_directories(dir / "fuzz_nrrd");
  fs::create_directories(dir / "fuzz_metaimage");
  const std::vector<ImageVolume> one = {volume(5, 4, 3, 0.0)};
  const std::vector<ImageVolume> two = {volume(4, 3, 2, 0.0), volume(4, 3, 2, 0.05)};
  write_image_series(dir / "fuzz_nifti" / "a.nii", one);
  write_image_series(dir / "fuzz_nifti" / "b.nii.gz", one);
  write_image_series(dir / "fuzz_nrrd" / "a.nrrd", one);
  write_image_series(dir / "fuzz_nrrd" / "series.nrrd", two);
  write_image_series(dir / "fuzz_metaimage" / "a.mha", one);
  write_image_series(dir / "fuzz_metaimage" / "series.mha", two);
  // A 3D Slicer segmentation: two named segments in one layer, raw voxels.
  std::string seg =
      "NRRD0004\n"
      "type: unsigned char\n"
      "dimension: 3\n"
      "space: left-posterior-superior\n"
      "sizes: 4 3 2\n"
      "space directions: (0.5,0,0) (0,0.5,0) (0,0,0.5)\n"
      "kinds: domain domain domain\n"
      "encoding: raw\n"
      "space origin: (1,2,3)\n"
      "Segment0_ID:=Segment_1\n"
      "Segment0_Name:=anterior leaflet\n"
      "Segment0_LabelValue:=1\n"
      "Segment0_Layer:=0\n"
      "Segment1_ID:=Segment_2\n"
      "Segment1_Name:=posterior leaflet\n"
      "Segment1_LabelValue:=2\n"
      "Segment1_Layer:=0\n"
      "\n";
  for (int i = 0; i < 24; ++i) seg.push_back(static_cast<char>(i % 3));
  spit(dir / "fuzz_nrrd" / "segmentation.seg.nrrd", seg);
}

void markups(const fs::path& dir) {
  const fs::path d = dir / "fuzz_markups";
  fs::create_directories(d);
  write_markups_json(d / "tmp.mrk.json", {{"A", {1.5, -2.0, 3.25}}, {"P", {0.0, 4.0, -1.0}}});
  with_selector(d / "tmp.mrk.json", '\0', d / "points.mrk.json");
  spit(d / "points.fcsv",
       std::string(1, '\1') +
           "# Markups fiducial file version = 4.11\n"
           "# CoordinateSystem = LPS\n"
           "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
           "vtkMRMLMarkupsFiducialNode_0,1.5,-2,3.25,0,0,0,1,1,1,0,A,,\n"
           "vtkMRMLMarkupsFiducialNode_1,0,4,-1,0,0,0,1,1,1,0,P,,\n");
}

void meshes(const fs::path& dir) {
  const fs::path d = dir / "fuzz_surface_mesh";
  fs::create_directories(d);
  TriangleMesh m;
  m.V.resize(4, 3);
  m.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.F.resize(4, 3);
  m.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  const char* endings[] = {".stl", ".ply", ".vtk", ".vtp"};
  for (char k = 0; k < 4; ++k) {
    const fs::path tmp = d / (std::string("tmp") + endings[static_cast<int>(k)]);
    write_surface_mesh(tmp, m, k % 2 ? "LPS" : "");
    with_selector(tmp, k, d / (std::string("tetrahedron") + endings[static_cast<int>(k)]));
  }
  const fs::path raw = d / "tmp_raw.vtp";
  write_surface_mesh(raw, m, "RAS", false);
  with_selector(raw, 3, d / "tetrahedron_uncompressed.vtp");
}

void result_files(const fs::path& dir) {
  for (const char* h : {"fuzz_patient", "fuzz_simulation", "fuzz_calibration", "fuzz_table"})
    fs::create_directories(dir / h);
  Patient p = make_virtual_patient(3);
  p.images = {volume(6, 5, 4, 0.0)};
  write_patient(dir / "fuzz_patient" / "virtual3.h5", p);

  const SimulationRecord r = test_support::sample_simulation_record();
  write_simulation_file(dir / "fuzz_simulation" / "simulation.h5", r);

  const CalibrationRecord c = test_support::sample_calibration_record();
  write_calibration_file(dir / "fuzz_calibration" / "calibration.h5", c);

  TableFile t;
  t.format = "mvtwin-cohort-study";
  t.attributes = {{"mvtwin_version", "seed"}, {"synthetic", "true"}};
  t.columns = {{"patient", "", {}, {"virtual-1", "virtual-2"}},
               {"error_after", "mm", {0.41, std::nan("")}, {}}};
  write_table_file(dir / "fuzz_table" / "study.h5", t);
}

void detector(const fs::path& dir) {
  const fs::path d = dir / "fuzz_detector_model";
  fs::create_directories(d);
  // The header of a model (no forests): what load() checks before the forests.
  spit(d / "header.yml", std::string(1, '\0') +
                             "%YAML:1.0\n---\n"
                             "format: mvtwin-valve-detector\n"
                             "format_version: 1\n"
                             "scales: [ 4., 2. ]\n"
                             "options:\n"
                             "   trees: 2\n"
                             "   max_depth: 4\n"
                             "   samples_per_volume: 10\n"
                             "   position_step_mm: 2.\n"
                             "   landmark_search_mm: 6.\n"
                             "   track_search_mm: 4.\n"
                             "   normal_search_mm: 3.\n"
                             "   surface_iterations: 2\n"
                             "   seed: 1\n"
                             "shape_model: [ 1., 2., 3. ]\n"
                             "landmark_offset: [ 0., 0., 0. ]\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: mvtwin_fuzz_seeds DIR\n";
    return 2;
  }
  try {
    const fs::path dir = argv[1];
    images(dir);
    markups(dir);
    meshes(dir);
    result_files(dir);
    detector(dir);
  } catch (const mvtwin::Error& e) {
    std::cerr << "mvtwin_fuzz_seeds: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
