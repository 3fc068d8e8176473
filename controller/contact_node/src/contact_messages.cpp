#include "poise/contact_node/contact_messages.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include "poise/node/convert.hpp"

namespace poise::contact_node {
namespace {

using node::put3;
using node::vec3;

}  // namespace

msg::ContactStatus to_msg(contact::ContactStatus s) noexcept {
  switch (s) {
    case contact::ContactStatus::kOk:
      return msg::CONTACT_OK;
    case contact::ContactStatus::kCompromised:
      return msg::CONTACT_PROJECTED;
    case contact::ContactStatus::kNoContact:
      return msg::CONTACT_NO_SUPPORT;
    case contact::ContactStatus::kIterationLimit:
      return msg::CONTACT_ITERATION_LIMIT;
    case contact::ContactStatus::kInvalidInput:
    case contact::ContactStatus::kSolverFailure:
      return msg::CONTACT_INVALID_INPUT;
  }
  return msg::CONTACT_INVALID_INPUT;
}

contact::ContactStatus from_msg(msg::ContactStatus s) noexcept {
  switch (s) {
    case msg::CONTACT_OK:
      return contact::ContactStatus::kOk;
    case msg::CONTACT_PROJECTED:
      return contact::ContactStatus::kCompromised;
    case msg::CONTACT_ITERATION_LIMIT:
      return contact::ContactStatus::kIterationLimit;
    case msg::CONTACT_NO_SUPPORT:
      return contact::ContactStatus::kNoContact;
    case msg::CONTACT_INVALID_INPUT:
      return contact::ContactStatus::kInvalidInput;
  }
  return contact::ContactStatus::kInvalidInput;
}

const char* from_msg(const msg::ContactProblem& in, contact::ContactProblem& out) noexcept {
  const char* error = nullptr;
  out.mass = in.mass();
  out.gravity = vec3(in.gravity_W());
  out.com = vec3(in.com_W());
  out.k_dot_desired = vec3(in.k_dot_desired_W());
  out.l_dot_desired = vec3(in.l_dot_desired_W());
  for (int i = 0; i < contact::kMaxFeet; ++i) {
    const msg::ContactFoot& f = in.feet()[i];
    contact::FootContact& o = out.feet[i];
    o.in_contact = f.in_contact();
    const auto& q = f.pose_W().orientation_wxyz();
    const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
    if (!(std::abs(quat.norm() - 1.0) <= 1e-6) && !error)
      error = i == 0 ? "feet[0].pose_W.orientation_wxyz is not a unit quaternion"
                     : "feet[1].pose_W.orientation_wxyz is not a unit quaternion";
    o.R_WF = quat.toRotationMatrix();
    o.p_WF = vec3(f.pose_W().position());
    o.sole = {f.x_min(), f.x_max(), f.y_min(), f.y_max()};
    o.safety_margin = f.safety_margin();
    o.ankle_height = f.ankle_height();
    o.mu = f.mu();
    o.mu_torsion = f.mu_torsion();
  }
  const msg::ContactWeights& w = in.weights();
  out.weights = contact::ContactWeights{};
  if (w.w_k() != 0.0 || w.eps_f() != 0.0 || w.eps_cop() != 0.0) {
    out.weights.w_k = w.w_k();
    out.weights.eps_f = w.eps_f();
    out.weights.eps_cop = w.eps_cop();
  }
  return error;
}

void to_msg(const contact::ContactProblem& in, msg::ContactProblem& out) noexcept {
  out.mass(in.mass);
  put3(in.gravity, out.gravity_W());
  put3(in.com, out.com_W());
  put3(in.k_dot_desired, out.k_dot_desired_W());
  put3(in.l_dot_desired, out.l_dot_desired_W());
  for (int i = 0; i < contact::kMaxFeet; ++i) {
    const contact::FootContact& f = in.feet[i];
    msg::ContactFoot& o = out.feet()[i];
    o.in_contact(f.in_contact);
    const Eigen::Quaterniond q(f.R_WF);
    o.pose_W().orientation_wxyz() = {q.w(), q.x(), q.y(), q.z()};
    put3(f.p_WF, o.pose_W().position());
    o.x_min(f.sole.x_min);
    o.x_max(f.sole.x_max);
    o.y_min(f.sole.y_min);
    o.y_max(f.sole.y_max);
    o.safety_margin(f.safety_margin);
    o.ankle_height(f.ankle_height);
    o.mu(f.mu);
    o.mu_torsion(f.mu_torsion);
  }
  out.weights().w_k(in.weights.w_k);
  out.weights().eps_f(in.weights.eps_f);
  out.weights().eps_cop(in.weights.eps_cop);
}

void to_msg(const contact::ContactSolution& in, const msg::Header& header, double solve_time_us,
            contact::Method method, msg::ContactSolution& out) noexcept {
  out.header(header);
  out.status(to_msg(in.status));
  put3(in.k_dot_admissible, out.k_dot_admissible_W());
  put3(in.l_dot_admissible, out.l_dot_admissible_W());
  for (int i = 0; i < contact::kMaxFeet; ++i) {
    const contact::FootWrench& f = in.feet[i];
    msg::ContactFootSolution& o = out.feet()[i];
    put3(f.force_W, o.wrench_at_ankle_W().force());
    put3(f.torque_ankle_W, o.wrench_at_ankle_W().torque());
    put3(f.cop_W, o.cop_W());
    o.cop_F() = {f.cop_F.x(), f.cop_F.y()};
    o.normal_torque(f.normal_torque);
  }
  out.solve_time_us(solve_time_us);
  out.method(static_cast<std::uint32_t>(method));
}

void from_msg(const msg::ContactSolution& in, contact::ContactSolution& out) noexcept {
  out.status = from_msg(in.status());
  out.k_dot_admissible = vec3(in.k_dot_admissible_W());
  out.l_dot_admissible = vec3(in.l_dot_admissible_W());
  for (int i = 0; i < contact::kMaxFeet; ++i) {
    const msg::ContactFootSolution& f = in.feet()[i];
    contact::FootWrench& o = out.feet[i];
    o.force_W = vec3(f.wrench_at_ankle_W().force());
    o.torque_ankle_W = vec3(f.wrench_at_ankle_W().torque());
    o.cop_W = vec3(f.cop_W());
    o.cop_F = Eigen::Vector2d(f.cop_F()[0], f.cop_F()[1]);
    o.normal_torque = f.normal_torque();
  }
}

}  // namespace poise::contact_node
