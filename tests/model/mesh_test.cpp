// Mesh files a URDF names (poise::model::read_mesh_vertices): COLLADA (.dae) as ROS reads it for
// a URDF (rviz, MoveIt's geometric_shapes), and its bad files refused naming the file.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "poise/model/mesh.hpp"
#include "poise/model/model.hpp"

namespace poise::model {
namespace {

namespace fs = std::filesystem;

fs::path write(const std::string& name, const std::string& text) {
  const fs::path dir = fs::path(POISE_BINARY_DIR) / "test_output" / "mesh_test";
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}

std::string numbers(const std::vector<Eigen::Vector3d>& v) {
  std::string s;
  char buf[96];
  for (const Eigen::Vector3d& p : v) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g ", p.x(), p.y(), p.z());
    s += buf;
  }
  return s;
}

// A COLLADA file with geometry `a` (its positions after a normal and a texture coordinate source,
// through an accessor of stride 4) placed twice by the visual scene: by a node that translates t,
// rotates by `deg` about z and scales by s (document order), and through <instance_node> of a
// library node under a parent node whose <matrix> translates by m; geometry `unused` is in no
// node. <unit meter> 0.01; <up_axis> Y_UP, which a URDF's mesh does not apply.
std::string dae(const std::vector<Eigen::Vector3d>& a, const Eigen::Vector3d& t, double deg,
                const Eigen::Vector3d& s, const Eigen::Vector3d& m) {
  std::string strided;
  char buf[128];
  for (const Eigen::Vector3d& p : a) {
    std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g 7 ", p.x(), p.y(), p.z());
    strided += buf;
  }
  const std::string n = std::to_string(a.size());
  std::string x = R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="unused"><mesh>
      <source id="unused-pos"><float_array id="unused-arr" count="3">100 100 100</float_array>
        <technique_common><accessor source="#unused-arr" count="1" stride="3"/></technique_common></source>
      <vertices id="unused-v"><input semantic="POSITION" source="#unused-pos"/></vertices>
    </mesh></geometry>
    <geometry id="a"><mesh>
      <source id="a-nrm"><float_array id="a-nrm-arr" count="3">0 0 1</float_array></source>
      <source id="a-pos"><float_array id="a-arr" count=")" + std::to_string(4 * a.size()) + R"(">)" + strided + R"(</float_array>
        <technique_common><accessor source="#a-arr" count=")" + n + R"(" stride="4">
          <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/><param name="W" type="float"/>
        </accessor></technique_common></source>
      <vertices id="a-v"><input semantic="NORMAL" source="#a-nrm"/><input semantic="POSITION" source="#a-pos"/></vertices>
      <triangles count="0"><input semantic="VERTEX" source="#a-v" offset="0"/><p></p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_nodes><node id="lib"><instance_geometry url="#a"/></node></library_nodes>
  <library_visual_scenes>
    <visual_scene id="other"><node><instance_geometry url="#unused"/></node></visual_scene>
    <visual_scene id="Scene">
      <node id="placed">)";
  std::snprintf(buf, sizeof buf, "<translate>%.17g %.17g %.17g</translate>", t.x(), t.y(), t.z());
  x += buf;
  std::snprintf(buf, sizeof buf, "<rotate>0 0 1 %.17g</rotate>", deg);
  x += buf;
  std::snprintf(buf, sizeof buf, "<scale>%.17g %.17g %.17g</scale>", s.x(), s.y(), s.z());
  x += buf;
  x += R"(<instance_geometry url="#a"/></node>
      <node id="parent"><matrix>1 0 0 )" + std::to_string(m.x()) + " 0 1 0 " +
       std::to_string(m.y()) + " 0 0 1 " + std::to_string(m.z()) + R"( 0 0 0 1</matrix>
        <node id="child"><instance_node url="#lib"/></node></node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
)";
  return x;
}

// Random vertices and placements (seeded); each vertex expected by hand: 0.01 (t + R s p) for
// the first node (R about z by deg, written out with cos and sin), 0.01 (m + p) for the second;
// nothing from the unused geometry or the visual scene the <scene> does not name.
TEST(Mesh, AColladaFileIsReadWithItsNodesAndUnitButNotItsUpAxis) {
  std::mt19937 rng(4242);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    SCOPED_TRACE(trial);
    std::vector<Eigen::Vector3d> a(3 + trial);
    for (auto& p : a) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d t(u(rng), u(rng), u(rng)), m(0.5, -0.25, 2.0);
    const Eigen::Vector3d s(1.0 + 0.5 * u(rng), 1.5, 2.0 + u(rng));
    const double deg = 180.0 * u(rng);
    const fs::path file = write("placed_" + std::to_string(trial) + ".dae", dae(a, t, deg, s, m));
    const std::vector<Eigen::Vector3d> v = read_mesh_vertices(file);
    ASSERT_EQ(v.size(), 2 * a.size()) << numbers(v);
    const double c = std::cos(deg * M_PI / 180.0), sn = std::sin(deg * M_PI / 180.0);
    for (std::size_t i = 0; i < a.size(); ++i) {
      const Eigen::Vector3d q(s.x() * a[i].x(), s.y() * a[i].y(), s.z() * a[i].z());
      const Eigen::Vector3d first(t.x() + c * q.x() - sn * q.y(), t.y() + sn * q.x() + c * q.y(),
                                  t.z() + q.z());
      EXPECT_LT((v[i] - 0.01 * first).norm(), 1e-12) << i;
      EXPECT_LT((v[a.size() + i] - 0.01 * (m + a[i])).norm(), 1e-12) << i;
    }
  }
}

// Without a visual scene every geometry is read as it stands (times the unit).
TEST(Mesh, AColladaFileWithoutASceneGivesEveryGeometry) {
  const fs::path file = write("no_scene.dae", R"(<COLLADA><library_geometries>
    <geometry id="g"><mesh><source id="p"><float_array id="pa" count="6">1 2 3 4 5 6</float_array></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices></mesh></geometry>
    </library_geometries></COLLADA>)");
  const std::vector<Eigen::Vector3d> v = read_mesh_vertices(file);
  ASSERT_EQ(v.size(), 2u);
  EXPECT_EQ(v[0], Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(v[1], Eigen::Vector3d(4, 5, 6));
}

// A bad file: ModelError naming the file and the problem; never a crash.
TEST(Mesh, BadColladaFilesAreRefusedNamingTheProblem) {
  const std::string geometry = R"(<library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="3">1 2 3</float_array></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices></mesh></geometry>
    </library_geometries>)";
  auto scene = [&](const std::string& node) {
    return "<COLLADA>" + geometry + "<library_visual_scenes><visual_scene id=\"s\"><node>" + node +
           "<instance_geometry url=\"#g\"/></node></visual_scene></library_visual_scenes></COLLADA>";
  };
  std::string deep = "<COLLADA>";
  for (int i = 0; i < 100000; ++i) deep += "<node>";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"<COLLADA><asset>", "not readable COLLADA XML"},
      {"<robot/>", "not <COLLADA>"},
      {deep, "nested deeper"},
      {scene("<matrix>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0</matrix>"), "15 numbers, not 16"},
      {scene("<rotate>0 0 1</rotate>"), "<rotate>"},
      {scene("<translate>1 x 3</translate>"), "<translate>"},
      {scene("<lookat>0 0 0 1 0 0 0 0 1</lookat>"), "<lookat>"},
      {"<COLLADA><asset><unit meter=\"-1\"/></asset>" + geometry + "</COLLADA>", "<unit meter>"},
      {"<COLLADA><library_geometries><geometry id=\"g\"><mesh><vertices><input semantic=\"POSITION\" "
       "source=\"#nowhere\"/></vertices></mesh></geometry></library_geometries></COLLADA>",
       "POSITION source is missing"},
      {"<COLLADA>" + geometry + "<library_visual_scenes><visual_scene id=\"s\"><node><instance_node "
       "url=\"#n\"/></node></visual_scene></library_visual_scenes><library_nodes><node id=\"n\">"
       "<instance_node url=\"#n\"/></node></library_nodes></COLLADA>",
       "deeper than 64"},
      {"<COLLADA><library_geometries/></COLLADA>", "no vertices"},
  };
  int i = 0;
  for (const auto& [text, expected] : cases) {
    const fs::path file = write("bad_" + std::to_string(i++) + ".dae", text);
    try {
      read_mesh_vertices(file);
      ADD_FAILURE() << "accepted: " << expected;
    } catch (const ModelError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(file.string()), std::string::npos) << what;
      EXPECT_NE(what.find(expected), std::string::npos) << what;
    }
  }
  try {
    read_mesh_vertices(write("mesh.ply", "ply\n"));
    ADD_FAILURE();
  } catch (const ModelError& e) {
    EXPECT_NE(std::string(e.what()).find("STL, OBJ and COLLADA"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace poise::model
