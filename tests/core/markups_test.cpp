#include "mvtwin/core/markups.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "mvtwin/core/error.h"

namespace mvtwin {
namespace {

namespace fs = std::filesystem;

fs::path markups_temp(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / "mvtwin_markups_test";
  fs::create_directories(d);
  return d / name;
}

void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

// A point list as 3D Slicer 5 writes it (the documentation's example layout): LPS positions.
TEST(Markups, SlicerJsonInLpsLandsAtRas) {
  const fs::path p = markups_temp("tips.mrk.json");
  write(
      p,
      R"({"@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json#",
"markups": [{"type": "Fiducial", "coordinateSystem": "LPS", "coordinateUnits": "mm", "controlPoints": [
  { "id": "1", "label": "anterolateral papillary tip", "position": [-53.5, -73.25, 10.0], "positionStatus": "defined" },
  { "id": "2", "label": "posteromedial papillary tip", "position": [49.75, -88.5, 0.0], "positionStatus": "defined" },
  { "id": "3", "label": "F-3", "position": [0.0, 0.0, 0.0], "positionStatus": "undefined" }
]}]})");
  const MarkupList m = read_markups(p);
  ASSERT_EQ(m.points.size(), 2u);
  EXPECT_EQ(m.coordinate_system, "LPS");
  EXPECT_EQ(m.points[0].label, "anterolateral papillary tip");
  EXPECT_EQ(m.points[0].position, Eigen::Vector3d(53.5, 73.25, 10.0));
  EXPECT_EQ(m.points[1].position, Eigen::Vector3d(-49.75, 88.5, 0.0));
  ASSERT_EQ(m.skipped.size(), 1u);

  // The same points written in RAS land at the same place; and our writer round-trips.
  const fs::path q = markups_temp("tips_ras.mrk.json");
  write(q, R"({"markups": [{"type": "Fiducial", "coordinateSystem": "RAS", "controlPoints": [
  { "label": "a", "position": [53.5, 73.25, 10.0] }]}]})");
  EXPECT_EQ(read_markups(q).points[0].position, m.points[0].position);
  const fs::path w = markups_temp("written.mrk.json");
  write_markups_json(w, m.points);
  const MarkupList back = read_markups(w);
  ASSERT_EQ(back.points.size(), 2u);
  EXPECT_TRUE(back.points[1].position.isApprox(m.points[1].position));
  EXPECT_EQ(back.points[1].label, m.points[1].label);
}

TEST(Markups, LegacyFcsv) {
  const fs::path p = markups_temp("tips.fcsv");
  write(p,
        "# Markups fiducial file version = 4.13\n# CoordinateSystem = LPS\n"
        "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
        "0,-19.5,13.25,29.0,0,0,0,1,1,1,0,PMPM,,\n1,-7.0,-76.5,17.5,0,0,0,1,1,1,0,ALPM,,\n");
  const MarkupList m = read_markups(p);
  ASSERT_EQ(m.points.size(), 2u);
  EXPECT_EQ(m.points[0].label, "PMPM");
  EXPECT_EQ(m.points[0].position, Eigen::Vector3d(19.5, -13.25, 29.0));
  const fs::path r = markups_temp("old.fcsv");  // Slicer 4.4's numeric code: 0 = RAS
  write(r,
        "# Markups fiducial file version = 4.4\n# CoordinateSystem = 0\n"
        "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
        "vtkMRMLMarkupsFiducialNode_0,-19.5,13.25,29.0,0,0,0,1,1,1,0,PMPM,,\n");
  EXPECT_EQ(read_markups(r).points[0].position, Eigen::Vector3d(-19.5, 13.25, 29.0));
}

TEST(Markups, BadFilesAreNamed) {
  auto expect = [](const fs::path& p, const std::string& text, const std::string& part) {
    write(p, text);
    try {
      read_markups(p);
      FAIL() << "expected an error for " << p;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect(markups_temp("ijk.mrk.json"),
         R"({"markups":[{"coordinateSystem":"IJK","controlPoints":[{"position":[1,2,3]}]}]})",
         "coordinate system 'IJK'");
  expect(markups_temp("broken.mrk.json"), R"({"markups":[{"controlPoints":[{"position":[1,2,)",
         "not a valid markups JSON");
  expect(markups_temp("nomarkups.mrk.json"), R"({"points":[]})", "no \"markups\" list");
  expect(markups_temp("nan.mrk.json"),
         R"({"markups":[{"controlPoints":[{"label":"x","position":[1,"a",3]}]}]})", "non-numeric");
  expect(markups_temp("empty.mrk.json"), R"({"markups":[{"controlPoints":[]}]})",
         "no defined control points");
  expect(markups_temp("bad.fcsv"), "# columns = id,x,y,z,label\n0,1,zz,3,a\n",
         "'zz' is not a number");
  EXPECT_THROW(read_markups(markups_temp("missing.mrk.json")), Error);
}

}  // namespace
}  // namespace mvtwin
