#include "poise/model/mesh.hpp"

#include <tinyxml.h>

#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <unordered_map>

#include "detail.hpp"
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

namespace {

// The vertices of a COLLADA (.dae) file, as ROS reads them for a URDF (rviz, MoveIt's
// geometric_shapes): every <instance_geometry> of the scene's visual scene placed by the
// transforms of the <node>s above it (<matrix>, <translate>, <rotate>, <scale>, in document
// order; <instance_node> followed), times <asset><unit meter>; <up_axis> is not applied (the
// mesh's axes are the URDF link's, whatever the exporter wrote). Without a visual scene, every
// geometry as it stands. Only positions are read (the POSITION input of each <mesh>'s
// <vertices>, through its <source>'s accessor).
class DaeVertices {
 public:
  DaeVertices(const std::string& data, const std::string& what) : what_(what) {
    detail::check_xml_depth(data, what_);
    doc_.Parse(data.c_str());
    if (doc_.Error())
      throw ModelError(what_ + ": not readable COLLADA XML (row " +
                       std::to_string(doc_.ErrorRow()) + ": " + doc_.ErrorDesc() + ")");
    root_ = doc_.RootElement();
    if (!root_ || std::strcmp(root_->Value(), "COLLADA") != 0)
      throw ModelError(what_ + ": the root element is not <COLLADA>");
    index(root_);
  }

  std::vector<Eigen::Vector3d> read() {
    double unit = 1.0;
    if (const TiXmlElement* asset = root_->FirstChildElement("asset"))
      if (const TiXmlElement* u = asset->FirstChildElement("unit"))
        if (const char* m = u->Attribute("meter")) {
          unit = number(m, "<unit meter>");
          if (!(unit > 0.0)) throw ModelError(what_ + ": <unit meter> must be > 0");
        }
    const TiXmlElement* scene = nullptr;
    if (const TiXmlElement* sc = root_->FirstChildElement("scene"))
      if (const TiXmlElement* inst = sc->FirstChildElement("instance_visual_scene"))
        scene = by_url(inst->Attribute("url"));
    if (!scene)
      if (const TiXmlElement* lib = root_->FirstChildElement("library_visual_scenes"))
        scene = lib->FirstChildElement("visual_scene");
    if (scene) {
      for (const TiXmlElement* n = scene->FirstChildElement("node"); n;
           n = n->NextSiblingElement("node"))
        visit(n, Eigen::Affine3d::Identity(), 0);
    } else if (const TiXmlElement* lib = root_->FirstChildElement("library_geometries")) {
      for (const TiXmlElement* g = lib->FirstChildElement("geometry"); g;
           g = g->NextSiblingElement("geometry"))
        add_geometry(g, Eigen::Affine3d::Identity());
    }
    for (Eigen::Vector3d& p : out_) p *= unit;
    return std::move(out_);
  }

 private:
  static constexpr int kMaxNodeDepth = 64;  // instance_node chains (and cycles) end here

  void index(const TiXmlElement* e) {
    for (; e; e = e->NextSiblingElement()) {
      if (const char* id = e->Attribute("id")) ids_.emplace(id, e);
      index(e->FirstChildElement());
    }
  }
  const TiXmlElement* by_url(const char* url) const {
    if (!url || url[0] != '#') return nullptr;  // another file's element: not followed
    const auto it = ids_.find(url + 1);
    return it == ids_.end() ? nullptr : it->second;
  }
  double number(const char* text, const char* where) const {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end == text || !std::isfinite(v))
      throw ModelError(what_ + ": " + where + " is not a number ('" + text + "')");
    return v;
  }
  std::vector<double> numbers(const TiXmlElement* e, const char* where) const {
    std::vector<double> v;
    const char* p = e ? e->GetText() : nullptr;
    if (!p) return v;
    while (true) {
      while (*p && std::isspace(static_cast<unsigned char>(*p))) ++p;
      if (!*p) break;
      char* end = nullptr;
      const double x = std::strtod(p, &end);
      if (end == p) throw ModelError(what_ + ": " + where + " holds something not a number");
      v.push_back(x);
      p = end;
    }
    return v;
  }

  // The node's own transform: its transformation elements composed in document order.
  Eigen::Affine3d local_transform(const TiXmlElement* node) const {
    Eigen::Affine3d T = Eigen::Affine3d::Identity();
    for (const TiXmlElement* c = node->FirstChildElement(); c; c = c->NextSiblingElement()) {
      const std::string tag = c->Value();
      if (tag == "matrix") {
        const std::vector<double> m = numbers(c, "<matrix>");
        if (m.size() != 16) throw ModelError(what_ + ": a <matrix> has " + std::to_string(m.size()) + " numbers, not 16");
        Eigen::Matrix4d M;
        for (int r = 0; r < 4; ++r)
          for (int k = 0; k < 4; ++k) M(r, k) = m[4 * r + k];  // row-major, column vectors
        T = T * Eigen::Affine3d(M);
      } else if (tag == "translate" || tag == "scale") {
        const std::vector<double> v = numbers(c, tag == "scale" ? "<scale>" : "<translate>");
        if (v.size() != 3) throw ModelError(what_ + ": a <" + tag + "> has " + std::to_string(v.size()) + " numbers, not 3");
        if (tag == "translate")
          T = T * Eigen::Translation3d(v[0], v[1], v[2]);
        else
          T = T * Eigen::Scaling(v[0], v[1], v[2]);
      } else if (tag == "rotate") {
        const std::vector<double> v = numbers(c, "<rotate>");
        if (v.size() != 4) throw ModelError(what_ + ": a <rotate> has " + std::to_string(v.size()) + " numbers, not 4 (axis, degrees)");
        const Eigen::Vector3d axis(v[0], v[1], v[2]);
        if (axis.norm() > 0.0)
          T = T * Eigen::AngleAxisd(v[3] * M_PI / 180.0, axis.normalized());
      } else if (tag == "lookat" || tag == "skew") {
        throw ModelError(what_ + ": a node's <" + tag + "> transform is not read (use <matrix>)");
      }
    }
    if (!T.matrix().allFinite()) throw ModelError(what_ + ": a node's transform is not finite");
    return T;
  }

  void visit(const TiXmlElement* node, const Eigen::Affine3d& parent, int depth) {
    if (depth > kMaxNodeDepth)
      throw ModelError(what_ + ": nodes nested (or instanced) deeper than " +
                       std::to_string(kMaxNodeDepth) + " levels");
    const Eigen::Affine3d T = parent * local_transform(node);
    for (const TiXmlElement* c = node->FirstChildElement(); c; c = c->NextSiblingElement()) {
      const std::string tag = c->Value();
      if (tag == "node") {
        visit(c, T, depth + 1);
      } else if (tag == "instance_node") {
        if (const TiXmlElement* n = by_url(c->Attribute("url"))) visit(n, T, depth + 1);
      } else if (tag == "instance_geometry") {
        if (const TiXmlElement* g = by_url(c->Attribute("url"))) add_geometry(g, T);
      }
    }
  }

  void add_geometry(const TiXmlElement* geometry, const Eigen::Affine3d& T) {
    const TiXmlElement* mesh = geometry->FirstChildElement("mesh");
    if (!mesh) return;  // <convex_mesh>, <spline>, <brep>: not read
    const TiXmlElement* vertices = mesh->FirstChildElement("vertices");
    if (!vertices) return;
    for (const TiXmlElement* in = vertices->FirstChildElement("input"); in;
         in = in->NextSiblingElement("input")) {
      const char* semantic = in->Attribute("semantic");
      if (!semantic || std::strcmp(semantic, "POSITION") != 0) continue;
      const TiXmlElement* source = by_url(in->Attribute("source"));
      if (!source) throw ModelError(what_ + ": a mesh's POSITION source is missing");
      const std::vector<double> v = numbers(source->FirstChildElement("float_array"), "a <float_array>");
      long stride = 3, offset = 0, count = static_cast<long>(v.size() / 3);
      if (const TiXmlElement* tc = source->FirstChildElement("technique_common"))
        if (const TiXmlElement* acc = tc->FirstChildElement("accessor")) {
          if (const char* s = acc->Attribute("stride")) stride = std::strtol(s, nullptr, 10);
          if (const char* s = acc->Attribute("offset")) offset = std::strtol(s, nullptr, 10);
          if (const char* s = acc->Attribute("count")) count = std::strtol(s, nullptr, 10);
        }
      if (stride < 3 || offset < 0 || count < 0)
        throw ModelError(what_ + ": a POSITION accessor has stride " + std::to_string(stride) +
                         ", offset " + std::to_string(offset) + " (needs stride >= 3, offset >= 0)");
      for (long i = 0; i < count; ++i) {
        const std::size_t k = static_cast<std::size_t>(offset + i * stride);
        if (k + 2 >= v.size()) break;
        const Eigen::Vector3d p(v[k], v[k + 1], v[k + 2]);
        if (p.allFinite()) out_.push_back(T * p);
      }
    }
  }

  std::string what_;
  TiXmlDocument doc_;
  const TiXmlElement* root_ = nullptr;
  std::unordered_map<std::string, const TiXmlElement*> ids_;
  std::vector<Eigen::Vector3d> out_;
};

}  // namespace

// Vertices of an STL (binary or ASCII), OBJ or COLLADA mesh, at most 64 MB. Throws ModelError
// naming the file.
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
  } else if (ext == ".dae") {
    v = DaeVertices(data, "mesh '" + path.string() + "'").read();
  } else {
    throw ModelError("mesh '" + path.string() + "': only STL, OBJ and COLLADA (.dae) meshes are read");
  }
  if (v.empty()) throw ModelError("mesh '" + path.string() + "': no vertices read");
  return v;
}

std::string read_collision_mesh(const std::string& filename, const Eigen::Vector3d& scale,
                                const fs::path& urdf_dir, std::vector<Eigen::Vector3d>& points) {
  points.clear();
  if (!scale.allFinite() || (scale.array().abs() < 1e-9).any()) {
    std::ostringstream os;
    os << "scale " << scale.transpose() << ": every factor must be finite and non-zero";
    return os.str();
  }
  const fs::path file = resolve_mesh_path(filename, urdf_dir);
  if (file.empty())
    return "not found (or not a regular file), looked for from " + urdf_dir.string() +
           " and its parents";
  try {
    points = read_mesh_vertices(file);
  } catch (const ModelError& e) {
    return e.what();
  }
  if (points.size() < 4)
    return file.string() + ": " + std::to_string(points.size()) +
           " vertices, fewer than a solid's 4";
  for (Eigen::Vector3d& p : points)
    p = p.cwiseProduct(scale);
  return "";
}

std::vector<std::string> collision_mesh_problems(const std::string& urdf_xml,
                                                 const fs::path& urdf_dir) {
  std::vector<std::string> problems;
  TiXmlDocument doc;
  doc.Parse(urdf_xml.c_str());
  const TiXmlElement* robot = doc.FirstChildElement("robot");
  if (robot == nullptr) return problems;  // the model's own checks say why
  std::vector<Eigen::Vector3d> points;
  for (const TiXmlElement* link = robot->FirstChildElement("link"); link != nullptr;
       link = link->NextSiblingElement("link"))
    for (const TiXmlElement* c = link->FirstChildElement("collision"); c != nullptr;
         c = c->NextSiblingElement("collision")) {
      const TiXmlElement* g = c->FirstChildElement("geometry");
      const TiXmlElement* mesh = g ? g->FirstChildElement("mesh") : nullptr;
      if (mesh == nullptr || mesh->Attribute("filename") == nullptr) continue;
      Eigen::Vector3d scale = Eigen::Vector3d::Ones();
      if (const char* s = mesh->Attribute("scale")) {
        std::istringstream in(s);
        for (int k = 0; k < 3; ++k)
          if (!(in >> scale[k])) scale[k] = std::nan("");
      }
      const std::string filename = mesh->Attribute("filename");
      const std::string why = read_collision_mesh(filename, scale, urdf_dir, points);
      if (!why.empty())
        problems.push_back("link '" + std::string(link->Attribute("name") ? link->Attribute("name")
                                                                            : "?") +
                           "': collision mesh '" + filename + "': " + why);
    }
  return problems;
}

}  // namespace poise::model
