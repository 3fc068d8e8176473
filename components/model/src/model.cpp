// Model building from URDF (urdfdom) and configuration helpers.
#include "poise/model/model.hpp"

#include <tinyxml.h>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

namespace poise::model {

namespace {

// ---- structural pre-check on the raw XML (urdfdom's own messages do not name loop links) -------

struct RawJoint {
  std::string name, type, parent, child;
  bool mimic = false;
};

void precheck_xml(const std::string& xml, const std::string& origin) {
  TiXmlDocument doc;
  doc.Parse(xml.c_str());
  if (doc.Error()) {
    std::ostringstream os;
    os << "URDF " << origin << ": bad XML at line " << doc.ErrorRow() << ", column "
       << doc.ErrorCol() << ": " << doc.ErrorDesc();
    throw ModelError(os.str());
  }
  const TiXmlElement* robot = doc.FirstChildElement("robot");
  if (robot == nullptr) throw ModelError("URDF " + origin + ": no <robot> element");

  std::set<std::string> links;
  for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr;
       e = e->NextSiblingElement("link")) {
    const char* name = e->Attribute("name");
    if (name == nullptr) throw ModelError("URDF " + origin + ": a <link> has no name");
    if (!links.insert(name).second)
      throw ModelError("URDF " + origin + ": link '" + name + "' is defined twice");
  }
  if (links.empty()) throw ModelError("URDF " + origin + ": no links");

  std::vector<RawJoint> joints;
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    RawJoint j;
    const char* name = e->Attribute("name");
    const char* type = e->Attribute("type");
    if (name == nullptr) throw ModelError("URDF " + origin + ": a <joint> has no name");
    j.name = name;
    j.type = type ? type : "";
    const TiXmlElement* p = e->FirstChildElement("parent");
    const TiXmlElement* c = e->FirstChildElement("child");
    if (p == nullptr || p->Attribute("link") == nullptr || c == nullptr ||
        c->Attribute("link") == nullptr)
      throw ModelError("URDF " + origin + ": joint '" + j.name + "' lacks a parent or child link");
    j.parent = p->Attribute("link");
    j.child = c->Attribute("link");
    j.mimic = e->FirstChildElement("mimic") != nullptr;
    if (!links.count(j.parent))
      throw ModelError("URDF " + origin + ": joint '" + j.name + "' has unknown parent link '" +
                       j.parent + "'");
    if (!links.count(j.child))
      throw ModelError("URDF " + origin + ": joint '" + j.name + "' has unknown child link '" +
                       j.child + "'");
    if (j.mimic)
      throw ModelError("URDF " + origin + ": joint '" + j.name +
                       "' is a mimic joint; mimic joints are not supported by poise::model "
                       "(model the coupling in the controller or remove <mimic>)");
    joints.push_back(j);
  }

  std::map<std::string, std::string> parent_of, joint_of;
  for (const RawJoint& j : joints) {
    if (j.parent == j.child)
      throw ModelError("URDF " + origin + ": kinematic loop: joint '" + j.name +
                       "' connects link '" + j.child + "' to itself");
    auto it = joint_of.find(j.child);
    if (it != joint_of.end())
      throw ModelError("URDF " + origin + ": kinematic loop: link '" + j.child +
                       "' is the child of two joints ('" + it->second + "' and '" + j.name +
                       "'); only trees are supported");
    joint_of[j.child] = j.name;
    parent_of[j.child] = j.parent;
  }
  // Every link must reach the root by following parents; a cycle never does.
  for (const std::string& l : links) {
    std::string cur = l;
    for (std::size_t steps = 0; parent_of.count(cur); ++steps) {
      if (steps > links.size())
        throw ModelError("URDF " + origin + ": kinematic loop through link '" + l +
                         "' (following its parent joints returns to it)");
      cur = parent_of[cur];
    }
  }
  std::vector<std::string> roots;
  for (const std::string& l : links)
    if (!parent_of.count(l)) roots.push_back(l);
  if (roots.size() > 1) {
    std::string all;
    for (const auto& r : roots)
      all += (all.empty() ? "'" : ", '") + r + "'";
    throw ModelError("URDF " + origin + ": several root links (" + all +
                     "); the model needs one tree");
  }
}

// Captures urdfdom's console_bridge messages so they can go into the exception text.
class CaptureHandler : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_WARN) {
      if (!messages.empty()) messages += "; ";
      messages += text;
    }
  }
  std::string messages;
};

std::mutex& urdfdom_mutex() {
  static std::mutex m;
  return m;
}

SE3 to_se3(const urdf::Pose& pose) {
  Eigen::Quaterniond qr(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z);
  const double n = qr.norm();
  if (!(n > 0.0))
    qr = Eigen::Quaterniond::Identity();
  else
    qr.coeffs() /= n;
  return SE3(qr.toRotationMatrix(), Vector3(pose.position.x, pose.position.y, pose.position.z));
}

Inertia link_inertia(const urdf::Link& link, const std::string& origin) {
  if (!link.inertial) return Inertia::Zero();  // URDF semantics: massless link
  const urdf::Inertial& in = *link.inertial;
  const std::string where = "URDF " + origin + ": link '" + link.name + "'";
  if (!std::isfinite(in.mass)) throw ModelError(where + ": mass is not finite");
  if (in.mass < 0.0) {
    std::ostringstream os;
    os << where << ": negative mass " << in.mass;
    throw ModelError(os.str());
  }
  Matrix3 I;
  I << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  if (!I.allFinite()) throw ModelError(where + ": inertia has non-finite entries");
  const Eigen::SelfAdjointEigenSolver<Matrix3> es(I, Eigen::EigenvaluesOnly);
  const Vector3 ev = es.eigenvalues();
  const double scale = std::max(1e-12, ev.cwiseAbs().maxCoeff());
  const bool pd = ev.minCoeff() > 1e-12 * scale && ev.minCoeff() > 0.0;
  const bool psd_zero = ev.cwiseAbs().maxCoeff() == 0.0;
  if ((in.mass > 0.0 && !pd) || (in.mass == 0.0 && !psd_zero && ev.minCoeff() < 0.0)) {
    std::ostringstream os;
    os << where << ": inertia matrix is not positive definite (eigenvalues " << ev.transpose()
       << ")";
    throw ModelError(os.str());
  }
  if (in.mass > 0.0) {
    const double tol = 1e-9 * ev.sum();
    if (ev(0) + ev(1) < ev(2) - tol) {
      std::ostringstream os;
      os << where << ": principal moments " << ev.transpose()
         << " violate the triangle inequality (not a physical rigid body)";
      throw ModelError(os.str());
    }
  }
  const SE3 X = to_se3(in.origin);
  return Inertia(in.mass, X.p, X.R * I * X.R.transpose());
}

struct Builder {
  Model& m;
  const std::string& origin;

  int add_body(int parent, JointType type, const SE3& X, const Vector3& axis,
               const std::string& link) {
    const int b = static_cast<int>(m.parent.size());
    m.parent.push_back(parent);
    m.joint_type.push_back(type);
    m.X_parent_joint.push_back(X);
    m.axis.push_back(axis);
    int id = -1;
    for (int k = 0; k < 3; ++k)
      if (axis == Vector3::Unit(k)) id = k;
    m.axis_id.push_back(id);
    m.inertia.push_back(Inertia::Zero());
    m.body_name.push_back(link);
    return b;
  }

  void visit(const urdf::Link& link, int body, const SE3& X_BL) {
    Frame fr;
    fr.name = link.name;
    fr.body = body;
    fr.X_BF = X_BL;
    fr.is_body = (m.body_name[body] == link.name);
    m.frames.push_back(fr);
    m.inertia[body] += link_inertia(link, origin).transformed(X_BL);

    std::vector<urdf::JointSharedPtr> children = link.child_joints;
    std::sort(children.begin(), children.end(),
              [](const auto& a, const auto& b) { return a->name < b->name; });
    for (const auto& j : children) {
      const urdf::Link* child = nullptr;
      for (const auto& cl : link.child_links)
        if (cl->name == j->child_link_name) child = cl.get();
      if (child == nullptr)
        throw ModelError("URDF " + origin + ": joint '" + j->name + "' has no child link");
      const SE3 X_BJ = X_BL * to_se3(j->parent_to_joint_origin_transform);
      if (j->mimic)
        throw ModelError("URDF " + origin + ": joint '" + j->name +
                         "' is a mimic joint; mimic joints are not supported");
      JointType type;
      switch (j->type) {
        case urdf::Joint::FIXED:
          visit(*child, body, X_BJ);
          continue;
        case urdf::Joint::REVOLUTE:
          type = JointType::kRevolute;
          break;
        case urdf::Joint::CONTINUOUS:
          type = JointType::kContinuous;
          break;
        case urdf::Joint::PRISMATIC:
          type = JointType::kPrismatic;
          break;
        default:
          throw ModelError("URDF " + origin + ": joint '" + j->name +
                           "' has an unsupported type (only fixed, revolute, continuous and "
                           "prismatic joints below the floating base)");
      }
      Vector3 axis(j->axis.x, j->axis.y, j->axis.z);
      if (!axis.allFinite() || axis.norm() < 1e-9)
        throw ModelError("URDF " + origin + ": joint '" + j->name + "' has a zero axis");
      axis.normalize();
      JointLimits lim;
      if (j->limits) {
        if (type != JointType::kContinuous) {
          lim.lower = j->limits->lower;
          lim.upper = j->limits->upper;
          if (lim.lower > lim.upper)
            throw ModelError("URDF " + origin + ": joint '" + j->name +
                             "' has lower limit above upper limit");
        }
        if (j->limits->velocity > 0.0) lim.velocity = j->limits->velocity;
        if (j->limits->effort > 0.0) lim.effort = j->limits->effort;
      }
      m.joint_names.push_back(j->name);
      m.limits.push_back(lim);
      m.damping.push_back(j->dynamics ? j->dynamics->damping : 0.0);
      m.friction.push_back(j->dynamics ? j->dynamics->friction : 0.0);
      const int nb = add_body(body, type, X_BJ, axis, child->name);
      visit(*child, nb, SE3::Identity());
    }
  }
};

}  // namespace

Model build_model_from_urdf_string(const std::string& xml, const std::string& origin) {
  precheck_xml(xml, origin);

  urdf::ModelInterfaceSharedPtr urdf_model;
  std::string messages;
  {
    std::lock_guard<std::mutex> lock(urdfdom_mutex());
    CaptureHandler handler;
    console_bridge::useOutputHandler(&handler);
    urdf_model = urdf::parseURDF(xml);
    console_bridge::restorePreviousOutputHandler();
    messages = handler.messages;
  }
  if (!urdf_model)
    throw ModelError("URDF " + origin + " rejected by urdfdom: " +
                     (messages.empty() ? std::string("unknown reason") : messages));
  const urdf::LinkConstSharedPtr root = urdf_model->getRoot();
  if (!root) throw ModelError("URDF " + origin + ": no root link");

  Model m;
  m.name = urdf_model->getName();
  Builder b{m, origin};
  b.add_body(-1, JointType::kFloating, SE3::Identity(), Vector3::Zero(), root->name);
  b.visit(*root, 0, SE3::Identity());

  m.nbodies = static_cast<int>(m.parent.size());
  m.njoints = m.nbodies - 1;
  m.nq = 7 + m.njoints;
  m.nv = 6 + m.njoints;
  m.support.resize(m.nbodies);
  m.subtree_end.resize(m.nbodies);
  for (int i = 0; i < m.nbodies; ++i) {
    if (i == 0) {
      m.support[0] = {0, 1, 2, 3, 4, 5};
    } else {
      m.support[i] = m.support[m.parent[i]];
      m.support[i].push_back(6 + i - 1);
    }
    m.subtree_end[i] = i;
  }
  for (int i = m.nbodies - 1; i > 0; --i)
    m.subtree_end[m.parent[i]] = std::max(m.subtree_end[m.parent[i]], m.subtree_end[i]);
  m.total_mass = 0.0;
  for (const Inertia& I : m.inertia)
    m.total_mass += I.mass;
  return m;
}

Model build_model_from_urdf_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw ModelError("URDF file not found: '" + path.string() + "'");
  if (std::filesystem::is_directory(path, ec))
    throw ModelError("URDF path is a directory, not a file: '" + path.string() + "'");
  std::ifstream in(path);
  if (!in) throw ModelError("cannot read URDF file '" + path.string() + "'");
  std::stringstream ss;
  ss << in.rdbuf();
  return build_model_from_urdf_string(ss.str(), "'" + path.string() + "'");
}

int Model::joint_index(const std::string& n) const {
  for (int j = 0; j < njoints; ++j)
    if (joint_names[j] == n) return j;
  throw ModelError("model '" + name + "' has no joint named '" + n + "'");
}

bool Model::has_joint(const std::string& n) const {
  return std::find(joint_names.begin(), joint_names.end(), n) != joint_names.end();
}

int Model::frame_id(const std::string& n) const {
  for (std::size_t f = 0; f < frames.size(); ++f)
    if (frames[f].name == n) return static_cast<int>(f);
  throw ModelError("model '" + name + "' has no link/frame named '" + n + "'");
}

bool Model::has_frame(const std::string& n) const {
  return std::any_of(frames.begin(), frames.end(), [&](const Frame& f) { return f.name == n; });
}

Eigen::VectorXd Model::neutral() const {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(nq);
  q(6) = 1.0;
  return q;
}

SE3 base_pose(const Eigen::Ref<const Eigen::VectorXd>& q) {
  const Eigen::Map<const Eigen::Quaterniond> quat(q.data() + 3);
  return SE3(quat.toRotationMatrix(), q.head<3>());
}

void set_base_pose(const SE3& X_WB, Eigen::Ref<Eigen::VectorXd> q) {
  q.head<3>() = X_WB.p;
  Eigen::Quaterniond quat(X_WB.R);
  quat.normalize();
  q.segment<4>(3) = quat.coeffs();
}

Motion base_velocity_from_world(const Matrix3& R_WB, const Vector3& v_WBo, const Vector3& omega_W) {
  Motion V;
  V.head<3>() = R_WB.transpose() * v_WBo;
  V.tail<3>() = R_WB.transpose() * omega_W;
  return V;
}

Motion base_velocity_to_world(const Matrix3& R_WB, const Motion& V_B) {
  Motion V;
  V.head<3>() = R_WB * V_B.head<3>();
  V.tail<3>() = R_WB * V_B.tail<3>();
  return V;
}

void integrate(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& q,
               const Eigen::Ref<const Eigen::VectorXd>& v, double dt,
               Eigen::Ref<Eigen::VectorXd> out) {
  const SE3 X = base_pose(q) * se3_exp(v.head<6>() * dt);
  const int n = model.njoints;
  out.tail(n) = q.tail(n) + dt * v.tail(n);
  set_base_pose(X, out);
}

void check_configuration(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& q) {
  if (q.size() != model.nq)
    throw ModelError("q has size " + std::to_string(q.size()) +
                     ", expected nq = " + std::to_string(model.nq));
  if (!q.allFinite()) throw ModelError("q has non-finite entries");
  const double n = q.segment<4>(3).norm();
  if (std::abs(n - 1.0) > 1e-6)
    throw ModelError("q[3:7] is not a unit quaternion (norm " + std::to_string(n) + ")");
}

void check_velocity(const Model& model, const Eigen::Ref<const Eigen::VectorXd>& v,
                    const char* what) {
  if (v.size() != model.nv)
    throw ModelError(std::string(what) + " has size " + std::to_string(v.size()) +
                     ", expected nv = " + std::to_string(model.nv));
  if (!v.allFinite()) throw ModelError(std::string(what) + " has non-finite entries");
}

}  // namespace poise::model
