/* Command checks and joint torque laws of the example driver. */
#include "safety.h"

#include <math.h>
#include <stdio.h>

const char *driver_mode_name(driver_mode m) {
  switch (m) {
    case DRIVER_STARTUP: return "STARTUP";
    case DRIVER_CONTROL: return "CONTROL";
    case DRIVER_HOLD: return "HOLD";
    case DRIVER_DAMP: return "DAMP";
    case DRIVER_ESTOP: return "ESTOP";
    case DRIVER_PROTECTIVE: return "PROTECTIVE_STOP";
  }
  return "?";
}

static double clamp_effort(const driver_joint *j, double tau) {
  if (j->effort > 0.0) {
    if (tau > j->effort) return j->effort;
    if (tau < -j->effort) return -j->effort;
  }
  return tau;
}

driver_reject driver_check_command(const poise_msg_JointCommand *cmd, int joint_count,
                                   char *field, size_t field_len) {
  if (cmd->mode != poise_msg_COMMAND_TORQUE && cmd->mode != poise_msg_COMMAND_DAMPING &&
      cmd->mode != poise_msg_COMMAND_ZERO) {
    snprintf(field, field_len, "mode = %d", (int)cmd->mode);
    return REJECT_MODE;
  }
  if (cmd->joint_count != (uint32_t)joint_count) {
    snprintf(field, field_len, "joint_count = %u (the robot has %d joints)",
             (unsigned)cmd->joint_count, joint_count);
    return REJECT_JOINT_COUNT;
  }
  /* Every number of a valid entry, whatever the mode: a NaN anywhere means the sender is broken. */
  const struct {
    const char *name;
    const double *v;
  } arrays[] = {{"tau_ff", cmd->tau_ff}, {"q_ref", cmd->q_ref}, {"qd_ref", cmd->qd_ref},
                {"kp", cmd->kp},         {"kd", cmd->kd}};
  for (size_t a = 0; a < sizeof arrays / sizeof arrays[0]; ++a) {
    for (int i = 0; i < joint_count; ++i) {
      if (!isfinite(arrays[a].v[i])) {
        snprintf(field, field_len, "%s[%d] = %g", arrays[a].name, i, arrays[a].v[i]);
        return REJECT_NON_FINITE;
      }
    }
  }
  for (int i = 0; i < joint_count; ++i) {
    if (cmd->kp[i] < 0.0 || cmd->kd[i] < 0.0) {
      snprintf(field, field_len, "%s[%d] = %g (gains must be >= 0)", cmd->kp[i] < 0.0 ? "kp" : "kd",
               i, cmd->kp[i] < 0.0 ? cmd->kp[i] : cmd->kd[i]);
      return REJECT_NEGATIVE_GAIN;
    }
  }
  return REJECT_NONE;
}

void driver_command_torques(const poise_msg_JointCommand *cmd, const driver_robot *robot,
                            const double *q, const double *qd, double *tau) {
  for (int i = 0; i < robot->joint_count; ++i) {
    double t = 0.0;
    switch (cmd->mode) {
      case poise_msg_COMMAND_TORQUE:
        t = cmd->tau_ff[i] + cmd->kp[i] * (cmd->q_ref[i] - q[i]) + cmd->kd[i] * (cmd->qd_ref[i] - qd[i]);
        break;
      case poise_msg_COMMAND_DAMPING: t = -cmd->kd[i] * qd[i]; break;
      case poise_msg_COMMAND_ZERO: t = 0.0; break;
    }
    tau[i] = clamp_effort(&robot->joints[i], t);
  }
}

void driver_hold_torques(const driver_robot *robot, const double *q_target, const double *q,
                         const double *qd, double *tau) {
  for (int i = 0; i < robot->joint_count; ++i) {
    const driver_joint *j = &robot->joints[i];
    tau[i] = clamp_effort(j, j->kp_hold * (q_target[i] - q[i]) - j->kd_hold * qd[i]);
  }
}

void driver_damp_torques(const driver_robot *robot, const double *qd, double *tau) {
  for (int i = 0; i < robot->joint_count; ++i) {
    const driver_joint *j = &robot->joints[i];
    tau[i] = clamp_effort(j, -j->kd_hold * qd[i]);
  }
}
