#include "poise/model/mesh.hpp"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "poise/model/model.hpp"

namespace poise::model {

namespace fs = std::filesystem;

// A mesh file of a URDF: "package://PKG/REST" is looked for as REST and PKG/REST in the URDF's
// folder and its parents (no ROS package index here), "file://PATH" and plain paths as given
// (relative: from the URDF's folder). Empty when not found.
fs::path resolve_mesh_path(const std::string& name, const fs::path& urdf_dir) {
  std::string n = name;
  std::vector<std::string> rel;
  if (n.rfind("package://", 0) == 0) {
    n = n.substr(10);
    const auto slash = n.find('/');
    if (slash != std::string::npos) rel.push_back(n.substr(slash + 1));
    rel.push_back(n);
  } else {
    if (n.rfind("file://", 0) == 0) n = n.substr(7);
    if (fs::path(n).is_absolute()) return fs::is_regular_file(n) ? fs::path(n) : fs::path();
    rel.push_back(n);
  }
  for (fs::path d = urdf_dir; !d.empty(); d = d.parent_path()) {
    for (const std::string& r : rel)
      if (fs::is_regular_file(d / r)) return d / r;
    if (d == d.parent_path()) break;
  }
  return {};
}

// Vertices of an STL (binary or ASCII) or OBJ mesh, at most 64 MB. Throws InitError naming the file.
std::vector<Eigen::Vector3d> read_mesh_vertices(const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const std::string data = read_text_file_limited(path, "mesh", std::size_t{64} << 20);
  std::vector<Eigen::Vector3d> v;
  auto ascii_vertices = [&](const char* tag) {
    std::istringstream in(data);
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream ls(line);
      std::string t;
      ls >> t;
      double x, y, z;
      if (t == tag && (ls >> x >> y >> z) && std::isfinite(x) && std::isfinite(y) && std::isfinite(z))
        v.emplace_back(x, y, z);
    }
  };
  if (ext == ".obj") {
    ascii_vertices("v");
  } else if (ext == ".stl") {
    std::uint32_t n = 0;
    if (data.size() >= 84) std::memcpy(&n, data.data() + 80, 4);
    if (data.size() >= 84 && data.size() == 84 + std::size_t{50} * n) {
      for (std::uint32_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
          float f[3];
          std::memcpy(f, data.data() + 84 + 50 * std::size_t{i} + 12 + 12 * k, 12);
          if (std::isfinite(f[0]) && std::isfinite(f[1]) && std::isfinite(f[2]))
            v.emplace_back(f[0], f[1], f[2]);
        }
    } else {
      ascii_vertices("vertex");
    }
  } else {
    throw ModelError("mesh '" + path.string() + "': only STL and OBJ meshes are read");
  }
  if (v.empty()) throw ModelError("mesh '" + path.string() + "': no vertices read");
  return v;
}

}  // namespace poise::model
