/* What the example driver needs to know about its robot, read from the two files that also go
 * on the wire in poise/robot_description: the URDF (expat) and the robot configuration YAML of
 * deploy/robots/ (libyaml). A real driver knows most of this from its own firmware; the point
 * here is that the description it publishes and the numbers it uses come from the same files. */
#ifndef POISE_C_DRIVER_ROBOT_FILES_H
#define POISE_C_DRIVER_ROBOT_FILES_H

#include <stddef.h>

#define DRIVER_MAX_JOINTS 64 /* MAX_JOINTS of idl/common.idl */
#define DRIVER_NAME_LEN 128

typedef struct driver_joint {
  char name[DRIVER_NAME_LEN];
  int has_limits;    /* URDF <limit> with lower < upper (revolute, prismatic) */
  double lower;      /* position limits [rad] or [m] */
  double upper;
  double effort;     /* |tau| limit [N m] or [N]; <= 0: none given */
  double q_initial;  /* robot.yaml nominal_posture, 0 when not listed [rad] or [m] */
  double kp_hold;    /* robot.yaml pd_gains (or its `default`) [N m/rad] */
  double kd_hold;    /* [N m s/rad] */
} driver_joint;

typedef struct driver_foot {
  char frame[DRIVER_NAME_LEN]; /* URDF link of the foot (ankle) frame F */
  double x_min, x_max, y_min, y_max;
  double height; /* F origin above the sole plane [m] */
} driver_foot;

typedef struct driver_robot {
  char name[DRIVER_NAME_LEN];
  char *urdf_text;   /* whole file, NUL-terminated (malloc) */
  char *config_text; /* whole robot.yaml, NUL-terminated (malloc) */
  char urdf_path[4096];

  int joint_count; /* movable URDF joints, in URDF document order (the wire order) */
  driver_joint joints[DRIVER_MAX_JOINTS];

  double mass; /* sum of the URDF link masses [kg] */
  char imu_frame[DRIVER_NAME_LEN];
  double imu_orientation_wxyz[4]; /* of the IMU frame in the base frame (fixed joints only) */
  driver_foot feet[2];            /* [0] right, [1] left */
  double safety_margin, mu, mu_torsion;
} driver_robot;

/* Reads robot.yaml at `config_path` and the URDF (`urdf_path`, or NULL: the yaml's `urdf:`
 * entry, relative to the yaml's folder). Returns 0, or -1 with a message in `err`. */
int driver_robot_load(const char *config_path, const char *urdf_path, driver_robot *robot,
                      char *err, size_t err_len);
void driver_robot_free(driver_robot *robot);

#endif
