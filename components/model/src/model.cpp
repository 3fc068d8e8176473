// Model building from URDF (urdfdom) and configuration helpers.
#include "poise/model/model.hpp"

#include "poise/cli/read_file.hpp"

#include "detail.hpp"

#include <tinyxml.h>

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string_view>
#include <fstream>
#include <cstdlib>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

namespace poise::model {

namespace detail {

// Element nesting depth of XML text, without building a tree (tinyxml recurses per level and
// overflows the stack on ~100,000 nested elements). Comments, CDATA, declarations and processing
// instructions are skipped; quoted attribute values may contain '>'. An approximation is enough:
// it only has to bound the depth tinyxml will see.
void check_xml_depth(const std::string& xml, const std::string& what) {
  int depth = 0;
  const std::size_t n = xml.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (xml[i] != '<') continue;
    if (xml.compare(i, 4, "<!--") == 0) {
      const std::size_t e = xml.find("-->", i + 4);
      if (e == std::string::npos) return;  // tinyxml reports the unterminated comment
      i = e + 2;
      continue;
    }
    if (xml.compare(i, 9, "<![CDATA[") == 0) {
      const std::size_t e = xml.find("]]>", i + 9);
      if (e == std::string::npos) return;
      i = e + 2;
      continue;
    }
    if (i + 1 < n && (xml[i + 1] == '?' || xml[i + 1] == '!')) {
      const std::size_t e = xml.find('>', i + 1);
      if (e == std::string::npos) return;
      i = e;
      continue;
    }
    const bool closing = i + 1 < n && xml[i + 1] == '/';
    // find the end of the tag, skipping quoted values
    std::size_t j = i + 1;
    char quote = 0;
    for (; j < n; ++j) {
      const char ch = xml[j];
      if (quote != 0) {
        if (ch == quote) quote = 0;
      } else if (ch == '"' || ch == '\'') {
        quote = ch;
      } else if (ch == '>' || ch == '<') {
        break;
      }
    }
    const bool self_closing = j < n && xml[j] == '>' && xml[j - 1] == '/';
    if (closing) {
      depth = std::max(0, depth - 1);
    } else if (!self_closing) {
      if (++depth > kMaxXmlDepth)
        throw ModelError(what + ": XML elements nested deeper than " +
                         std::to_string(kMaxXmlDepth) + " levels (refused before parsing)");
    }
    if (j >= n) return;
    i = j - (xml[j] == '<' ? 1 : 0);
  }
}

}  // namespace detail

namespace {

// ---- limits and pre-checks on the raw text, before tinyxml and urdfdom see it ------------------

// Joins collected problems, one per line (each line is a complete message naming its subject).
/// An element of another XML namespace (`drake:declare_convex`): not URDF, ignored.
bool is_namespaced(const TiXmlElement* e) {
  return e->ValueStr().find(':') != std::string::npos;
}

/// Removes every element of another XML namespace below `e`; their names (with counts) go to
/// `removed`. True when one was removed.
bool strip_namespaced(TiXmlElement* e, std::map<std::string, int>& removed) {
  bool any = false;
  for (TiXmlElement* c = e->FirstChildElement(); c != nullptr;) {
    TiXmlElement* next = c->NextSiblingElement();
    if (is_namespaced(c)) {
      ++removed[c->ValueStr()];
      e->RemoveChild(c);
      any = true;
    } else {
      any = strip_namespaced(c, removed) || any;
    }
    c = next;
  }
  return any;
}

/// One note naming the elements of other XML namespaces in the URDF text ("" when none).
std::string namespaced_note(const std::string& xml) {
  if (xml.find(':') == std::string::npos) return "";
  TiXmlDocument doc;
  doc.Parse(xml.c_str());
  TiXmlElement* robot = doc.FirstChildElement("robot");
  std::map<std::string, int> found;
  if (robot == nullptr || !strip_namespaced(robot, found)) return "";
  std::string names;
  for (const auto& [name, n] : found)
    names += (names.empty() ? "" : ", ") + name + " (" + std::to_string(n) + ")";
  return "elements of other XML namespaces are ignored: " + names;
}

std::string join_lines(const std::vector<std::string>& errs, std::size_t max_lines = 60) {
  std::string out;
  for (std::size_t i = 0; i < errs.size() && i < max_lines; ++i)
    out += (i == 0 ? "" : "\n") + errs[i];
  if (errs.size() > max_lines)
    out += "\n... and " + std::to_string(errs.size() - max_lines) + " more problems";
  return out;
}

// Strict number: the whole (trimmed) text must be one number. False for text and empty strings;
// true with a non-finite value for nan / inf / out-of-range values (the caller says which).
bool parse_number(std::string_view s, double& out) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ptr != s.data() + s.size()) return false;
  if (ec == std::errc::result_out_of_range) {
    out = std::numeric_limits<double>::infinity();
    return true;
  }
  return ec == std::errc();
}

std::string quoted_attr(const char* attr, const char* v) {
  std::string t = v;
  if (t.size() > 40) t = t.substr(0, 40) + "...";
  return std::string(attr) + "=\"" + t + "\"";
}

struct RawJoint {
  std::string name, type, parent, child;
};

constexpr double kInf = std::numeric_limits<double>::infinity();

class RawChecker {
 public:
  explicit RawChecker(const std::string& origin) : origin_(origin) {}
  std::vector<std::string> errors;

  void err(const std::string& where, const std::string& what) {
    errors.push_back("URDF " + origin_ + ": " + where + ": " + what);
  }

  // A scalar attribute: nullopt when missing (error if required) or bad (error).
  std::optional<double> scalar(const TiXmlElement* e, const char* attr, const std::string& where,
                               bool required, double lo, double hi) {
    const char* v = e->Attribute(attr);
    const std::string at = where + ": <" + e->ValueStr() + "> ";
    if (v == nullptr) {
      if (required) err(at + attr, "missing");
      return std::nullopt;
    }
    double x = 0.0;
    if (!parse_number(v, x)) {
      err(at + quoted_attr(attr, v), "not a number");
      return std::nullopt;
    }
    if (!std::isfinite(x)) {
      err(at + quoted_attr(attr, v), "not a finite number");
      return std::nullopt;
    }
    if (x < lo || x > hi) {
      std::ostringstream os;
      os << "out of the accepted range [" << lo << ", " << hi << "]";
      err(at + quoted_attr(attr, v), os.str());
      return std::nullopt;
    }
    return x;
  }

  // A 3-vector attribute ("x y z"), each entry finite with |entry| <= bound.
  std::optional<Vector3> vec3(const TiXmlElement* e, const char* attr, const std::string& where,
                              bool required, double bound) {
    const char* v = e->Attribute(attr);
    const std::string at = where + ": <" + e->ValueStr() + "> ";
    if (v == nullptr) {
      if (required) err(at + attr, "missing");
      return std::nullopt;
    }
    std::istringstream is{std::string(v)};
    std::string tok;
    std::vector<double> xs;
    while (is >> tok) {
      double x = 0.0;
      if (!parse_number(tok, x)) {
        err(at + quoted_attr(attr, v), "'" + tok.substr(0, 20) + "' is not a number");
        return std::nullopt;
      }
      if (!std::isfinite(x)) {
        err(at + quoted_attr(attr, v), "not finite");
        return std::nullopt;
      }
      xs.push_back(x);
    }
    if (xs.size() != 3) {
      err(at + quoted_attr(attr, v), "expected 3 numbers, got " + std::to_string(xs.size()));
      return std::nullopt;
    }
    const Vector3 r(xs[0], xs[1], xs[2]);
    if (r.cwiseAbs().maxCoeff() > bound) {
      std::ostringstream os;
      os << "implausible: an entry exceeds " << bound << " in magnitude";
      err(at + quoted_attr(attr, v), os.str());
      return std::nullopt;
    }
    return r;
  }

  // At most one child element named `child` (urdfdom silently uses the first).
  const TiXmlElement* single(const TiXmlElement* e, const char* child, const std::string& where) {
    const TiXmlElement* first = e->FirstChildElement(child);
    if (first != nullptr && first->NextSiblingElement(child) != nullptr)
      err(where, std::string("<") + e->ValueStr() + "> has more than one <" + child + ">");
    return first;
  }

  void origin(const TiXmlElement* e, const std::string& where) {
    const TiXmlElement* o = single(e, "origin", where);
    if (o == nullptr) return;
    const std::string w = where + " <" + e->ValueStr() + ">";
    vec3(o, "xyz", w, false, kMaxOffset);
    vec3(o, "rpy", w, false, kMaxOffset);
  }

  void geometry(const TiXmlElement* shape_owner, const std::string& where, bool collision) {
    origin(shape_owner, where);
    const TiXmlElement* g = single(shape_owner, "geometry", where);
    const std::string w = where + " <" + shape_owner->ValueStr() + "><geometry>";
    if (g == nullptr) {
      err(where, "<" + shape_owner->ValueStr() + "> has no <geometry>");
      return;
    }
    // Elements of other XML namespaces (Drake's <drake:declare_convex/>) are not shapes: ignored
    // (precheck_xml removes them; the model notes them).
    auto next_shape = [](const TiXmlElement* e) {
      while (e != nullptr && is_namespaced(e)) e = e->NextSiblingElement();
      return e;
    };
    const TiXmlElement* s = next_shape(g->FirstChildElement());
    if (s == nullptr) {
      err(w, "no shape");
      return;
    }
    if (next_shape(s->NextSiblingElement()) != nullptr)
      err(w, "more than one shape (<" + s->ValueStr() + "> and <" +
                 next_shape(s->NextSiblingElement())->ValueStr() + ">)");
    const double lo = collision ? std::numeric_limits<double>::min() : 0.0;
    const std::string t = s->ValueStr();
    if (t == "box") {
      if (auto v = vec3(s, "size", w, true, kMaxOffset))
        if (v->minCoeff() < lo)
          err(w + ": <box> size", collision ? "every size must be > 0" : "sizes must be >= 0");
    } else if (t == "sphere") {
      // radius 0: a contact point (Drake's point contacts), accepted in a collision too
      scalar(s, "radius", w, true, 0.0, kMaxOffset);
    } else if (t == "cylinder" || t == "capsule") {
      scalar(s, "radius", w, true, lo, kMaxOffset);
      scalar(s, "length", w, true, lo, kMaxOffset);
    } else if (t == "mesh") {
      if (s->Attribute("filename") == nullptr) err(w + ": <mesh> filename", "missing");
      vec3(s, "scale", w, false, 1e6);
    } else {
      err(w, "unknown shape <" + t + ">");
    }
  }

  void link(const TiXmlElement* e, const std::string& name) {
    const std::string where = "link '" + name + "'";
    if (const TiXmlElement* in = single(e, "inertial", where)) {
      const std::string w = where + " <inertial>";
      origin(in, where);
      const TiXmlElement* mass = single(in, "mass", w);
      if (mass == nullptr)
        err(w, "no <mass>");
      else if (const auto m = scalar(mass, "value", w, true, -kInf, kInf)) {
        std::ostringstream os;
        if (*m < 0.0) {
          os << "negative mass " << *m;
          err(w + ": <mass> value", os.str());
        } else if (*m > kMaxLinkMass) {
          os << "implausible mass " << *m << " kg (limit " << kMaxLinkMass << " kg per link)";
          err(w + ": <mass> value", os.str());
        }
      }
      const TiXmlElement* I = single(in, "inertia", w);
      if (I == nullptr) {
        err(w, "no <inertia>");
      } else {
        for (const char* a : {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"})
          scalar(I, a, w, true, -kMaxInertia, kMaxInertia);
      }
    }
    for (const TiXmlElement* c = e->FirstChildElement("collision"); c != nullptr;
         c = c->NextSiblingElement("collision"))
      geometry(c, where, true);
    for (const TiXmlElement* v = e->FirstChildElement("visual"); v != nullptr;
         v = v->NextSiblingElement("visual"))
      geometry(v, where, false);
  }

  void joint(const TiXmlElement* e, const RawJoint& j, const std::set<std::string>& joint_names) {
    const std::string where = "joint '" + j.name + "'";
    for (const char* c : {"parent", "child", "axis", "limit", "dynamics", "mimic"})
      single(e, c, where);
    origin(e, where);
    static const std::set<std::string> kTypes = {"revolute", "continuous", "prismatic", "fixed"};
    if (j.type.empty()) {
      err(where, "no type");
      return;
    }
    if (!kTypes.count(j.type)) {
      err(where, "unsupported type '" + j.type +
                     "' (only fixed, revolute, continuous and prismatic joints "
                     "below the floating base" +
                     (j.type == "floating"
                          ? std::string("; a floating joint is taken as the floating base only "
                                        "from a massless root link without geometry whose only "
                                        "joint it is")
                          : std::string()) +
                     ")");
      return;
    }
    if (j.type == "fixed") return;  // axis, limits, dynamics and <mimic> of a fixed joint unused
    if (const TiXmlElement* a = e->FirstChildElement("axis"))
      if (auto v = vec3(a, "xyz", where, false, 1e6))
        if (v->norm() < 1e-9) err(where + ": <axis> xyz", "zero axis");
    const TiXmlElement* lim = e->FirstChildElement("limit");
    const bool prismatic = j.type == "prismatic";
    if (lim == nullptr) {
      if (j.type != "continuous") err(where, "a " + j.type + " joint needs a <limit>");
    } else {
      const double inf = std::numeric_limits<double>::infinity();
      // 0: a joint that is not actuated (hands' passive joints write effort="0" velocity="0"):
      // frozen like a mimic joint (visit below); a negative limit is a defect.
      const auto eff = scalar(lim, "effort", where, true, -inf, inf);
      if (eff && !(*eff >= 0.0))
        err(where + ": <limit> effort", "must be >= 0 (0: not actuated, the joint is frozen)");
      const auto vel = scalar(lim, "velocity", where, true, -inf, inf);
      if (vel && !(*vel >= 0.0))
        err(where + ": <limit> velocity", "must be >= 0 (0: not actuated, the joint is frozen)");
      if (j.type != "continuous") {
        const double b = prismatic ? kMaxOffset : inf;
        const auto lo = scalar(lim, "lower", where, false, -b, b);
        const auto hi = scalar(lim, "upper", where, false, -b, b);
        if (lo && hi && *lo > *hi) {
          std::ostringstream os;
          os << "lower " << *lo << " > upper " << *hi;
          err(where + ": <limit>", os.str());
        }
      }
    }
    if (const TiXmlElement* d = e->FirstChildElement("dynamics")) {
      scalar(d, "damping", where, false, 0.0, 1e9);
      scalar(d, "friction", where, false, 0.0, 1e9);
    }
    if (const TiXmlElement* mi = e->FirstChildElement("mimic")) {
      const char* leader = mi->Attribute("joint");
      if (leader == nullptr)
        err(where + ": <mimic>", "no joint attribute");
      else if (!joint_names.count(leader))
        err(where + ": <mimic joint=\"" + std::string(leader) + "\">", "no such joint");
      else if (j.name == leader)
        err(where + ": <mimic>", "mimics itself");
      scalar(mi, "multiplier", where, false, -1e6, 1e6);
      scalar(mi, "offset", where, false, -1e6, 1e6);
    }
  }

 private:
  std::string origin_;
};

// Parses the URDF text; returns its one <robot> element.
const TiXmlElement* parse_robot_element(TiXmlDocument& doc, const std::string& xml,
                                        const std::string& origin) {
  detail::check_xml_depth(xml, "URDF " + origin);
  doc.Parse(xml.c_str());
  if (doc.Error()) {
    std::ostringstream os;
    os << "URDF " << origin << ": bad XML at line " << doc.ErrorRow() << ", column "
       << doc.ErrorCol() << ": " << doc.ErrorDesc();
    throw ModelError(os.str());
  }
  const TiXmlElement* robot = doc.FirstChildElement("robot");
  if (robot == nullptr) throw ModelError("URDF " + origin + ": no <robot> element");
  if (robot->NextSiblingElement("robot") != nullptr)
    throw ModelError("URDF " + origin + ": more than one <robot> element");
  return robot;
}

// A dummy root link and the floating joint below it (both empty: none).
struct DummyRoot {
  std::string link, joint;
};

// A massless root link whose only joint is a `floating` one to the robot (URDFs written for
// Drake, converted from MJCF, or for Gazebo: `world` -> floating -> pelvis): that joint is the
// floating base Poise adds anyway; the dummy link and the joint are dropped below and the
// joint's child is the root. A `floating` joint anywhere else is refused (RawChecker::joint).
DummyRoot find_dummy_root(const TiXmlElement* robot) {
  DummyRoot dummy;
  std::map<std::string, int> joints_below;
  std::set<std::string> child_links;
  const TiXmlElement* floating = nullptr;
  int nfloating = 0;
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    const TiXmlElement* p = e->FirstChildElement("parent");
    const TiXmlElement* c = e->FirstChildElement("child");
    if (p && p->Attribute("link")) ++joints_below[p->Attribute("link")];
    if (c && c->Attribute("link")) child_links.insert(c->Attribute("link"));
    const char* type = e->Attribute("type");
    if (type && std::string(type) == "floating") {
      floating = e;
      ++nfloating;
    }
  }
  const TiXmlElement* fp = floating ? floating->FirstChildElement("parent") : nullptr;
  if (nfloating == 1 && fp && fp->Attribute("link") && floating->Attribute("name")) {
    const std::string parent = fp->Attribute("link");
    const TiXmlElement* link = nullptr;
    for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr;
         e = e->NextSiblingElement("link"))
      if (e->Attribute("name") && parent == e->Attribute("name")) link = e;
    double mass = 0.0;
    if (link)
      if (const TiXmlElement* in = link->FirstChildElement("inertial"))
        if (const TiXmlElement* me = in->FirstChildElement("mass"))
          if (me->Attribute("value")) mass = std::strtod(me->Attribute("value"), nullptr);
    if (link && !child_links.count(parent) && joints_below[parent] == 1 && mass == 0.0 &&
        !link->FirstChildElement("collision") && !link->FirstChildElement("visual")) {
      dummy.link = parent;
      dummy.joint = floating->Attribute("name");
    }
  }
  return dummy;
}

void check_element_counts(const TiXmlElement* robot, const std::string& origin) {
  std::size_t nlinks = 0, njoints = 0;
  for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr;
       e = e->NextSiblingElement("link"))
    ++nlinks;
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint"))
    ++njoints;
  if (nlinks > kMaxLinks || njoints > kMaxLinks)
    throw ModelError("URDF " + origin + ": " + std::to_string(nlinks) + " links and " +
                     std::to_string(njoints) + " joints; at most " + std::to_string(kMaxLinks) +
                     " of each are accepted");
}

// Checks every <link> but the dummy root; returns their names.
std::set<std::string> check_links(const TiXmlElement* robot, const DummyRoot& dummy,
                                  RawChecker& ck) {
  std::set<std::string> links;
  for (const TiXmlElement* e = robot->FirstChildElement("link"); e != nullptr;
       e = e->NextSiblingElement("link")) {
    const char* name = e->Attribute("name");
    if (name == nullptr || *name == '\0') {
      ck.err("a <link>", "has no name");
      continue;
    }
    if (name == dummy.link) continue;
    if (!links.insert(name).second) ck.err("link '" + std::string(name) + "'", "defined twice");
    ck.link(e, name);
  }
  return links;
}

std::set<std::string> check_joint_names(const TiXmlElement* robot, RawChecker& ck) {
  std::set<std::string> joint_names;
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    const char* name = e->Attribute("name");
    if (name != nullptr && !joint_names.insert(name).second)
      ck.err("joint '" + std::string(name) + "'", "defined twice");
  }
  return joint_names;
}

// Checks every <joint> but the dummy root's; returns those between two known links.
std::vector<RawJoint> check_joints(const TiXmlElement* robot, const std::set<std::string>& links,
                                   const DummyRoot& dummy, RawChecker& ck) {
  const std::set<std::string> joint_names = check_joint_names(robot, ck);
  std::vector<RawJoint> joints;
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    RawJoint j;
    const char* name = e->Attribute("name");
    const char* type = e->Attribute("type");
    if (name == nullptr || *name == '\0') {
      ck.err("a <joint>", "has no name");
      continue;
    }
    j.name = name;
    j.type = type ? type : "";
    if (j.name == dummy.joint) continue;
    ck.joint(e, j, joint_names);
    const TiXmlElement* p = e->FirstChildElement("parent");
    const TiXmlElement* c = e->FirstChildElement("child");
    if (p == nullptr || p->Attribute("link") == nullptr || c == nullptr ||
        c->Attribute("link") == nullptr) {
      ck.err("joint '" + j.name + "'", "lacks a parent or child link");
      continue;
    }
    j.parent = p->Attribute("link");
    j.child = c->Attribute("link");
    bool ok = true;
    if (!links.count(j.parent)) {
      ck.err("joint '" + j.name + "'", "unknown parent link '" + j.parent + "'");
      ok = false;
    }
    if (!links.count(j.child)) {
      ck.err("joint '" + j.name + "'", "unknown child link '" + j.child + "'");
      ok = false;
    }
    if (ok) joints.push_back(j);
  }
  return joints;
}

// The parent link of every child link; refuses a link that is the child of two joints.
std::map<std::string, std::string> parent_links(const std::vector<RawJoint>& joints,
                                                RawChecker& ck) {
  std::map<std::string, std::string> parent_of, joint_of;
  for (const RawJoint& j : joints) {
    if (j.parent == j.child) {
      ck.err("joint '" + j.name + "'",
             "kinematic loop: connects link '" + j.child + "' to itself");
      continue;
    }
    auto it = joint_of.find(j.child);
    if (it != joint_of.end()) {
      ck.err("link '" + j.child + "'", "kinematic loop: the child of two joints ('" +
                                           it->second + "' and '" + j.name +
                                           "'); only trees are supported");
      continue;
    }
    joint_of[j.child] = j.name;
    parent_of[j.child] = j.parent;
  }
  return parent_of;
}

// Refuses a cycle and a tree deeper than kMaxTreeDepth; returns whether there is a cycle.
bool check_tree_depth(const std::set<std::string>& links,
                      const std::map<std::string, std::string>& parent_of, RawChecker& ck) {
  // Depth of every link below its root, memoised (linear time); a cycle never reaches a root.
  std::map<std::string, long> depth;  // -1: on the current path
  bool cycle = false;
  for (const std::string& l : links) {
    if (depth.count(l)) continue;
    std::vector<std::string> path;
    std::string cur = l;
    long base = 0;
    while (true) {
      auto d = depth.find(cur);
      if (d != depth.end()) {
        if (d->second < 0) {
          if (!cycle)
            ck.err("link '" + cur + "'",
                   "kinematic loop (following its parent joints returns to it)");
          cycle = true;
          base = 0;
        } else {
          base = d->second + 1;
        }
        break;
      }
      depth[cur] = -1;
      path.push_back(cur);
      auto p = parent_of.find(cur);
      if (p == parent_of.end()) {
        base = 0;
        depth[cur] = 0;
        path.pop_back();
        base = 1;
        break;
      }
      cur = p->second;
    }
    for (auto it = path.rbegin(); it != path.rend(); ++it) depth[*it] = base++;
  }
  long max_depth = 0;
  std::string deepest;
  for (const auto& [l, d] : depth)
    if (d > max_depth) {
      max_depth = d;
      deepest = l;
    }
  if (!cycle && max_depth > static_cast<long>(kMaxTreeDepth))
    ck.err("link '" + deepest + "'", "is " + std::to_string(max_depth) +
                                         " joints below the root; at most " +
                                         std::to_string(kMaxTreeDepth) + " are accepted");
  return cycle;
}

void check_single_root(const std::set<std::string>& links,
                       const std::map<std::string, std::string>& parent_of, bool cycle,
                       RawChecker& ck) {
  std::vector<std::string> roots;
  for (const std::string& l : links)
    if (!parent_of.count(l)) roots.push_back(l);
  if (roots.size() > 1) {
    std::string all;
    for (std::size_t i = 0; i < roots.size() && i < 10; ++i)
      all += (all.empty() ? "'" : ", '") + roots[i] + "'";
    if (roots.size() > 10) all += ", ...";
    ck.err("several root links (" + all + ")", "the model needs one tree");
  } else if (roots.empty() && !cycle) {
    ck.err("links", "no root link (kinematic loop)");
  }
}

// Removes what urdfdom is not to see; returns whether anything was removed.
bool strip_for_urdfdom(TiXmlDocument& doc, const DummyRoot& dummy) {
  bool stripped = false;
  if (!dummy.link.empty()) {
    TiXmlElement* r = doc.FirstChildElement("robot");
    for (const char* kind : {"link", "joint"})
      for (TiXmlElement* e = r->FirstChildElement(kind); e != nullptr;) {
        TiXmlElement* next = e->NextSiblingElement(kind);
        const char* n = e->Attribute("name");
        if (n && std::string(n) == (std::string(kind) == "link" ? dummy.link : dummy.joint))
          r->RemoveChild(e);
        e = next;
      }
    stripped = true;
  }
  // <visual> elements: Poise draws nothing, and urdfdom 3.0 refuses some that other tools accept
  // (a <material> without a name: the link is then dropped with its collisions; Unitree's H1-2).
  // Their geometry was checked above.
  for (TiXmlElement* e = doc.FirstChildElement("robot")->FirstChildElement("link"); e != nullptr;
       e = e->NextSiblingElement("link")) {
    while (TiXmlElement* v = e->FirstChildElement("visual")) {
      e->RemoveChild(v);
      stripped = true;
    }
  }
  for (TiXmlElement* e = doc.FirstChildElement("robot")->FirstChildElement("joint"); e != nullptr;
       e = e->NextSiblingElement("joint")) {
    const char* type = e->Attribute("type");
    if (type == nullptr || std::string(type) != "fixed") continue;
    while (TiXmlElement* mi = e->FirstChildElement("mimic")) {
      e->RemoveChild(mi);
      stripped = true;
    }
  }
  std::map<std::string, int> foreign;
  stripped = strip_namespaced(doc.FirstChildElement("robot"), foreign) || stripped;
  return stripped;
}

// Checks the raw XML; returns the text urdfdom is to parse: `xml` itself, or a copy without the
// <mimic> elements of fixed joints (legal URDF, meaningless there, ignored).
std::string precheck_xml(const std::string& xml, const std::string& origin) {
  TiXmlDocument doc;
  const TiXmlElement* robot = parse_robot_element(doc, xml, origin);
  const DummyRoot dummy = find_dummy_root(robot);

  RawChecker ck(origin);
  check_element_counts(robot, origin);
  const std::set<std::string> links = check_links(robot, dummy, ck);
  if (links.empty()) throw ModelError(join_lines(ck.errors) + (ck.errors.empty() ? "" : "\n") +
                                      "URDF " + origin + ": no links");
  const std::vector<RawJoint> joints = check_joints(robot, links, dummy, ck);
  const auto parent_of = parent_links(joints, ck);
  const bool cycle = check_tree_depth(links, parent_of, ck);
  check_single_root(links, parent_of, cycle, ck);
  if (!ck.errors.empty()) throw ModelError(join_lines(ck.errors));

  if (!strip_for_urdfdom(doc, dummy)) return xml;
  TiXmlPrinter printer;
  doc.Accept(&printer);
  return printer.CStr();
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

// One link's inertia in its link frame. Per link only what no merging can repair is refused (a
// negative principal moment); positive definiteness and the triangle inequality are checked on
// each body after its fixed links are merged into it (check_body), so a massless or degenerate
// leaf on a fixed joint is fine. The raw pre-check has already refused non-finite values.
Inertia link_inertia(const urdf::Link& link, const std::string& origin,
                     std::vector<std::string>& errors) {
  if (!link.inertial) return Inertia::Zero();  // URDF semantics: massless link
  const urdf::Inertial& in = *link.inertial;
  const std::string where = "URDF " + origin + ": link '" + link.name + "'";
  Matrix3 I;
  I << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  if (!std::isfinite(in.mass) || in.mass < 0.0 || !I.allFinite()) {
    std::ostringstream os;
    os << where << ": mass " << in.mass << " or inertia not finite / negative";
    errors.push_back(os.str());
    return Inertia::Zero();
  }
  if (in.mass > 0.0 && in.mass < kMinBodyMass) {
    std::ostringstream os;
    os << where << ": mass " << in.mass << " kg; a link needs at least " << kMinBodyMass
       << " kg (or exactly 0 for a massless link)";
    errors.push_back(os.str());
    return Inertia::Zero();
  }
  const Eigen::SelfAdjointEigenSolver<Matrix3> es(I, Eigen::EigenvaluesOnly);
  const Vector3 ev = es.eigenvalues();
  const double scale = std::max(1e-12, ev.cwiseAbs().maxCoeff());
  if (ev.minCoeff() < -1e-9 * scale) {
    std::ostringstream os;
    os << where << ": inertia matrix is not positive definite (a negative principal moment; "
       << "eigenvalues " << ev.transpose() << ")";
    errors.push_back(os.str());
    return Inertia::Zero();
  }
  const SE3 X = to_se3(in.origin);
  return Inertia(in.mass, X.p, X.R * I * X.R.transpose());
}

// A body (its link plus the links merged into it by fixed joints) must be a physical rigid body.
void check_body(const Model& m, int b, const std::string& origin,
                std::vector<std::string>& errors) {
  const Inertia& in = m.inertia[b];
  std::string merged;
  for (const Frame& f : m.frames)
    if (f.body == b && !f.is_body) merged += (merged.empty() ? "'" : ", '") + f.name + "'";
  const std::string where = "URDF " + origin + ": link '" + m.body_name[b] + "'" +
                            (merged.empty() ? "" : " (with the fixed links " + merged + ")");
  // A massless link between two joints is a common way to write a 2- or 3-axis joint; a mass
  // above zero but below kMinBodyMass (1e-320, a typo) is not, and a floating base needs mass.
  if ((b == 0 && !(in.mass >= kMinBodyMass)) || (in.mass > 0.0 && in.mass < kMinBodyMass)) {
    std::ostringstream os;
    os << where << ": mass " << in.mass << " kg; " << (b == 0 ? "the floating base" : "a body")
       << " needs at least " << kMinBodyMass << " kg"
       << (b == 0 ? " (an <inertial> with a mass)" : " (or exactly 0 for a massless link)");
    errors.push_back(os.str());
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Matrix3> es(in.I_com, Eigen::EigenvaluesOnly);
  const Vector3 ev = es.eigenvalues();
  const double scale = std::max(1e-12, ev.cwiseAbs().maxCoeff());
  if (in.mass > 0.0) {
    if (!(ev.minCoeff() > 1e-12 * scale && ev.minCoeff() > 0.0)) {
      std::ostringstream os;
      os << where << ": inertia matrix is not positive definite (eigenvalues " << ev.transpose()
         << ")";
      errors.push_back(os.str());
      return;
    }
    const double tol = 1e-9 * ev.sum();
    if (ev(0) + ev(1) < ev(2) - tol) {
      std::ostringstream os;
      os << where << ": principal moments " << ev.transpose()
         << " violate the triangle inequality (not a physical rigid body)";
      errors.push_back(os.str());
    }
  } else if (ev.minCoeff() < -1e-9 * scale) {
    std::ostringstream os;
    os << where << ": massless but its inertia has negative eigenvalues " << ev.transpose();
    errors.push_back(os.str());
  }
}

// Every joint moves some mass: the bodies at and below it weigh at least kMinBodyMass (a massless
// leaf has no inertia for a gain or an acceleration to act on: robot init wrote kp: -nan).
void check_moved_mass(const Model& m, const std::string& origin,
                      std::vector<std::string>& errors) {
  std::vector<double> below(m.parent.size(), 0.0);
  for (int b = static_cast<int>(m.parent.size()) - 1; b >= 0; --b) {
    below[b] += m.inertia[b].mass;
    if (m.parent[b] >= 0) below[m.parent[b]] += below[b];
  }
  for (std::size_t b = 1; b < m.parent.size(); ++b)
    if (!(below[b] >= kMinBodyMass))
      errors.push_back("URDF " + origin + ": the joint moving link '" + m.body_name[b] +
                       "' moves no mass (it and every link below it are massless); give the "
                       "link an <inertial> or make the joint fixed");
}

struct Builder {
  Model& m;
  const std::string& origin;
  std::vector<std::string> errors;

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
    m.inertia[body] += link_inertia(link, origin, errors).transformed(X_BL);

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
      const bool unactuated = j->type != urdf::Joint::FIXED && j->limits &&
                              (j->limits->effort == 0.0 || j->limits->velocity == 0.0);
      if ((j->mimic && j->type != urdf::Joint::FIXED) || unactuated) {
        // Frozen: made fixed at the mimic formula with its leader at 0 (= offset), or at 0 for a
        // joint whose <limit> says it is not actuated (effort or velocity 0), clamped to the
        // joint's limits (components/model/README.md "Mimic joints").
        double x = j->mimic ? j->mimic->offset : 0.0;
        if (j->limits && j->type != urdf::Joint::CONTINUOUS)
          x = std::clamp(x, j->limits->lower, std::max(j->limits->lower, j->limits->upper));
        Vector3 a(j->axis.x, j->axis.y, j->axis.z);
        if (!a.allFinite() || a.norm() < 1e-9) a = Vector3::UnitX();
        a.normalize();
        SE3 X_JC = SE3::Identity();
        if (j->type == urdf::Joint::PRISMATIC)
          X_JC.p = x * a;
        else
          X_JC.R = Eigen::AngleAxisd(x, a).toRotationMatrix();
        std::ostringstream os;
        if (j->mimic)
          os << "joint '" << j->name << "' mimics '" << j->mimic->joint_name
             << "': frozen (treated as fixed) at " << x;
        else
          os << "joint '" << j->name << "': <limit> effort " << j->limits->effort << " velocity "
             << j->limits->velocity << ", not actuated: frozen (treated as fixed) at " << x;
        m.notes.push_back(os.str());
        m.frozen_joints.push_back(j->name);
        visit(*child, body, X_BJ * X_JC);
        continue;
      }
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

std::string urdf_for_urdfdom(const std::string& xml, const std::string& origin) {
  if (xml.size() > kMaxFileBytes)
    throw ModelError("URDF " + origin + ": " + std::to_string(xml.size()) +
                     " bytes, larger than the limit of " + std::to_string(kMaxFileBytes) +
                     " bytes");
  if (xml.find('\0') != std::string::npos)
    throw ModelError("URDF " + origin + ": contains a NUL byte (binary data, not XML)");
  return precheck_xml(xml, origin);
}

Model build_model_from_urdf_string(const std::string& xml, const std::string& origin) {
  const std::string checked = urdf_for_urdfdom(xml, origin);

  urdf::ModelInterfaceSharedPtr urdf_model;
  std::string messages;
  {
    std::lock_guard<std::mutex> lock(urdfdom_mutex());
    CaptureHandler handler;
    console_bridge::useOutputHandler(&handler);
    urdf_model = urdf::parseURDF(checked);
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
  Builder b{m, origin, {}};
  b.add_body(-1, JointType::kFloating, SE3::Identity(), Vector3::Zero(), root->name);
  b.visit(*root, 0, SE3::Identity());
  for (int body = 0; body < static_cast<int>(m.parent.size()); ++body)
    check_body(m, body, origin, b.errors);
  check_moved_mass(m, origin, b.errors);
  double total = 0.0;
  for (const Inertia& I : m.inertia) total += I.mass;
  if (total > kMaxTotalMass) {
    std::ostringstream os;
    os << "URDF " << origin << ": total mass " << total << " kg exceeds " << kMaxTotalMass
       << " kg (implausible for a robot)";
    b.errors.push_back(os.str());
  }
  const int moving = static_cast<int>(m.parent.size()) - 1;
  if (moving > kMaxWireJoints)
    b.errors.push_back("URDF " + origin + ": " + std::to_string(moving) +
                       " moving joints; Poise's messages carry at most " +
                       std::to_string(kMaxWireJoints) +
                       " (MAX_JOINTS of idl/common.idl): fix the extra joints in the URDF");
  if (!b.errors.empty()) throw ModelError(join_lines(b.errors));

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
  if (const std::string note = namespaced_note(xml); !note.empty()) m.notes.push_back(note);
  return m;
}

std::string read_text_file_limited(const std::filesystem::path& path, const std::string& what,
                                   std::size_t max_bytes) {
  try {
    return cli::read_regular_file(path, what, max_bytes);
  } catch (const cli::FileError& e) {
    throw ModelError(e.what());
  }
}

Model build_model_from_urdf_file(const std::filesystem::path& path) {
  std::string origin(1, '\'');  // appended: GCC 12 warns (-Wrestrict) on "'" + s
  origin += path.string();
  origin += '\'';
  return build_model_from_urdf_string(read_text_file_limited(path, "URDF"), origin);
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
