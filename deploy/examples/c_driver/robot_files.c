/* Robot files of the example driver: URDF through expat, robot.yaml through libyaml. */
#define _POSIX_C_SOURCE 200809L

#include "robot_files.h"

#include <errno.h>
#include <expat.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <yaml.h>

#define URDF_MAX_ALL_JOINTS 256
#define URDF_MAX_DEPTH 16

static void set_err(char *err, size_t len, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(err, len, fmt, ap);
  va_end(ap);
}

static void copy_name(char *dst, const char *src) {
  snprintf(dst, DRIVER_NAME_LEN, "%s", src ? src : "");
}

/* Whole file into a NUL-terminated malloc'ed buffer; NULL and `err` on failure. */
static char *read_text_file(const char *path, const char *what, char *err, size_t err_len) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    set_err(err, err_len, "cannot open the %s '%s': %s", what, path, strerror(errno));
    return NULL;
  }
  size_t cap = 65536, len = 0;
  char *buf = malloc(cap);
  while (buf) {
    if (len + 1 >= cap) {
      char *bigger = realloc(buf, cap * 2);
      if (!bigger) {
        free(buf);
        buf = NULL;
        break;
      }
      buf = bigger;
      cap *= 2;
    }
    const size_t n = fread(buf + len, 1, cap - len - 1, f);
    if (n == 0) break;
    len += n;
  }
  const int failed = ferror(f);
  fclose(f);
  if (!buf || failed) {
    free(buf);
    set_err(err, err_len, "cannot read the %s '%s'", what, path);
    return NULL;
  }
  buf[len] = '\0';
  return buf;
}

/* ------------------------------------------------------------------------------------------ */
/* URDF */

typedef struct urdf_joint {
  char name[DRIVER_NAME_LEN], type[32], parent[DRIVER_NAME_LEN], child[DRIVER_NAME_LEN];
  double rpy[3];
  int has_limit;
  double lower, upper, effort;
} urdf_joint;

typedef struct urdf_state {
  XML_Parser parser;
  const char *stack[URDF_MAX_DEPTH]; /* element names from the root; only the first few kept */
  char stack_buf[URDF_MAX_DEPTH][32];
  int depth;
  urdf_joint joints[URDF_MAX_ALL_JOINTS];
  int joint_count;
  int in_joint; /* index + 1 of the <joint> being read (a child of <robot>) */
  double mass;
  char error[256];
} urdf_state;

static const char *attr(const XML_Char **atts, const char *name) {
  for (int i = 0; atts[i]; i += 2)
    if (strcmp(atts[i], name) == 0) return atts[i + 1];
  return NULL;
}

static double attr_number(const XML_Char **atts, const char *name, double fallback) {
  const char *v = attr(atts, name);
  if (!v) return fallback;
  char *end = NULL;
  const double x = strtod(v, &end);
  return (end && end != v) ? x : fallback;
}

static void XMLCALL urdf_start(void *data, const XML_Char *el, const XML_Char **atts) {
  urdf_state *s = data;
  const int d = s->depth; /* 0: <robot> */
  if (d < URDF_MAX_DEPTH) {
    snprintf(s->stack_buf[d], sizeof s->stack_buf[d], "%s", el);
    s->stack[d] = s->stack_buf[d];
  }
  s->depth++;
  if (d == 0 && strcmp(el, "robot") != 0) {
    snprintf(s->error, sizeof s->error, "the root element is <%s>, not <robot>", el);
    XML_StopParser(s->parser, XML_FALSE);
    return;
  }
  if (d == 1 && strcmp(el, "joint") == 0) { /* <joint> inside <transmission> is depth 2 */
    if (s->joint_count >= URDF_MAX_ALL_JOINTS) {
      snprintf(s->error, sizeof s->error, "more than %d joints", URDF_MAX_ALL_JOINTS);
      XML_StopParser(s->parser, XML_FALSE);
      return;
    }
    urdf_joint *j = &s->joints[s->joint_count++];
    memset(j, 0, sizeof *j);
    copy_name(j->name, attr(atts, "name"));
    snprintf(j->type, sizeof j->type, "%s", attr(atts, "type") ? attr(atts, "type") : "");
    s->in_joint = s->joint_count;
    return;
  }
  if (d == 2 && s->in_joint) {
    urdf_joint *j = &s->joints[s->in_joint - 1];
    if (strcmp(el, "parent") == 0) copy_name(j->parent, attr(atts, "link"));
    if (strcmp(el, "child") == 0) copy_name(j->child, attr(atts, "link"));
    if (strcmp(el, "origin") == 0 && attr(atts, "rpy"))
      sscanf(attr(atts, "rpy"), "%lf %lf %lf", &j->rpy[0], &j->rpy[1], &j->rpy[2]);
    if (strcmp(el, "limit") == 0) {
      j->has_limit = 1;
      j->lower = attr_number(atts, "lower", 0.0);
      j->upper = attr_number(atts, "upper", 0.0);
      j->effort = attr_number(atts, "effort", 0.0);
    }
    return;
  }
  /* <robot><link><inertial><mass value=".."/> */
  if (d == 3 && strcmp(el, "mass") == 0 && strcmp(s->stack[1], "link") == 0 &&
      strcmp(s->stack[2], "inertial") == 0)
    s->mass += attr_number(atts, "value", 0.0);
}

static void XMLCALL urdf_end(void *data, const XML_Char *el) {
  urdf_state *s = data;
  (void)el;
  s->depth--;
  if (s->depth == 1) s->in_joint = 0;
}

static int is_movable(const char *type) {
  return strcmp(type, "revolute") == 0 || strcmp(type, "continuous") == 0 ||
         strcmp(type, "prismatic") == 0;
}

/* Quaternion helpers, w x y z. */
static void quat_mul(const double a[4], const double b[4], double out[4]) {
  const double w = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  const double x = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  const double y = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  const double z = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
  out[0] = w;
  out[1] = x;
  out[2] = y;
  out[3] = z;
}

/* URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll). */
static void quat_from_rpy(const double rpy[3], double q[4]) {
  const double qx[4] = {cos(rpy[0] / 2), sin(rpy[0] / 2), 0, 0};
  const double qy[4] = {cos(rpy[1] / 2), 0, sin(rpy[1] / 2), 0};
  const double qz[4] = {cos(rpy[2] / 2), 0, 0, sin(rpy[2] / 2)};
  double zy[4];
  quat_mul(qz, qy, zy);
  quat_mul(zy, qx, q);
}

static int parse_urdf(driver_robot *r, char *err, size_t err_len) {
  urdf_state *s = calloc(1, sizeof *s);
  if (!s) {
    set_err(err, err_len, "out of memory");
    return -1;
  }
  s->parser = XML_ParserCreate(NULL);
  XML_SetUserData(s->parser, s);
  XML_SetElementHandler(s->parser, urdf_start, urdf_end);
  const int ok = XML_Parse(s->parser, r->urdf_text, (int)strlen(r->urdf_text), XML_TRUE) ==
                 XML_STATUS_OK;
  if (!ok) {
    if (s->error[0])
      set_err(err, err_len, "URDF '%s': %s", r->urdf_path, s->error);
    else
      set_err(err, err_len, "URDF '%s' line %lu: %s", r->urdf_path,
              (unsigned long)XML_GetCurrentLineNumber(s->parser),
              XML_ErrorString(XML_GetErrorCode(s->parser)));
    XML_ParserFree(s->parser);
    free(s);
    return -1;
  }
  XML_ParserFree(s->parser);

  r->joint_count = 0;
  for (int i = 0; i < s->joint_count; ++i) {
    const urdf_joint *j = &s->joints[i];
    if (!is_movable(j->type)) continue;
    if (r->joint_count >= DRIVER_MAX_JOINTS) {
      set_err(err, err_len, "URDF '%s' has more than %d movable joints (MAX_JOINTS)",
              r->urdf_path, DRIVER_MAX_JOINTS);
      free(s);
      return -1;
    }
    driver_joint *d = &r->joints[r->joint_count++];
    memset(d, 0, sizeof *d);
    copy_name(d->name, j->name);
    d->has_limits = j->has_limit && strcmp(j->type, "continuous") != 0 && j->lower < j->upper;
    d->lower = j->lower;
    d->upper = j->upper;
    d->effort = j->has_limit ? j->effort : 0.0;
  }
  r->mass = s->mass;
  if (r->joint_count == 0 || !(r->mass > 0.0)) {
    set_err(err, err_len, "URDF '%s': %d movable joints, total mass %g kg", r->urdf_path,
            r->joint_count, r->mass);
    free(s);
    return -1;
  }

  /* Orientation of the IMU link in the base (root) link: walk up through fixed joints. The
   * gantry holds the base level, so this is also the IMU's orientation in W. */
  double q[4] = {1, 0, 0, 0};
  char link[DRIVER_NAME_LEN];
  copy_name(link, r->imu_frame);
  for (int guard = 0; guard < URDF_MAX_ALL_JOINTS; ++guard) {
    const urdf_joint *up = NULL;
    for (int i = 0; i < s->joint_count; ++i)
      if (strcmp(s->joints[i].child, link) == 0) up = &s->joints[i];
    if (!up) break; /* reached the root */
    if (strcmp(up->type, "fixed") != 0) {
      set_err(err, err_len,
              "imu_frame '%s' is not rigidly attached to the base (joint '%s' is %s): this "
              "example driver reports the IMU of a base held still",
              r->imu_frame, up->name, up->type);
      free(s);
      return -1;
    }
    double qj[4], qn[4];
    quat_from_rpy(up->rpy, qj);
    quat_mul(qj, q, qn);
    memcpy(q, qn, sizeof q);
    copy_name(link, up->parent);
  }
  memcpy(r->imu_orientation_wxyz, q, sizeof q);
  free(s);
  return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* robot.yaml */

static yaml_node_t *map_get(yaml_document_t *doc, yaml_node_t *map, const char *key) {
  if (!map || map->type != YAML_MAPPING_NODE) return NULL;
  for (yaml_node_pair_t *p = map->data.mapping.pairs.start; p < map->data.mapping.pairs.top; ++p) {
    yaml_node_t *k = yaml_document_get_node(doc, p->key);
    if (k && k->type == YAML_SCALAR_NODE && strcmp((const char *)k->data.scalar.value, key) == 0)
      return yaml_document_get_node(doc, p->value);
  }
  return NULL;
}

static const char *scalar(yaml_node_t *n) {
  return (n && n->type == YAML_SCALAR_NODE) ? (const char *)n->data.scalar.value : NULL;
}

/* Number at `map`.`key`; -1 and `err` naming `where`.`key` when missing or not a number. */
static int get_number(yaml_document_t *doc, yaml_node_t *map, const char *where, const char *key,
                      double *out, char *err, size_t err_len) {
  const char *v = scalar(map_get(doc, map, key));
  char *end = NULL;
  if (v) *out = strtod(v, &end);
  if (!v || end == v || *end != '\0' || !isfinite(*out)) {
    set_err(err, err_len, "robot.yaml: %s%s%s: %s", where, where[0] ? "." : "", key,
            v ? "not a finite number" : "missing");
    return -1;
  }
  return 0;
}

static int get_string(yaml_document_t *doc, yaml_node_t *map, const char *where, const char *key,
                      char *out, size_t out_len, char *err, size_t err_len) {
  const char *v = scalar(map_get(doc, map, key));
  if (!v || !v[0]) {
    set_err(err, err_len, "robot.yaml: %s%s%s: missing", where, where[0] ? "." : "", key);
    return -1;
  }
  snprintf(out, out_len, "%s", v);
  return 0;
}

static int joint_index(const driver_robot *r, const char *name) {
  for (int j = 0; j < r->joint_count; ++j)
    if (strcmp(r->joints[j].name, name) == 0) return j;
  return -1;
}

/* Per-joint values from nominal_posture and pd_gains (names checked against the URDF). */
static int read_joint_tables(yaml_document_t *doc, yaml_node_t *root, driver_robot *r,
                             char *err, size_t err_len) {
  yaml_node_t *posture = map_get(doc, root, "nominal_posture");
  if (posture && posture->type == YAML_MAPPING_NODE) {
    for (yaml_node_pair_t *p = posture->data.mapping.pairs.start;
         p < posture->data.mapping.pairs.top; ++p) {
      const char *name = scalar(yaml_document_get_node(doc, p->key));
      const int j = name ? joint_index(r, name) : -1;
      if (j < 0) {
        set_err(err, err_len, "robot.yaml: nominal_posture.%s: not a movable URDF joint",
                name ? name : "?");
        return -1;
      }
      const char *v = scalar(yaml_document_get_node(doc, p->value));
      char *end = NULL;
      const double x = v ? strtod(v, &end) : NAN;
      if (!v || end == v || *end != '\0' || !isfinite(x)) {
        set_err(err, err_len, "robot.yaml: nominal_posture.%s: not a finite number", name);
        return -1;
      }
      r->joints[j].q_initial = x;
    }
  }
  yaml_node_t *gains = map_get(doc, root, "pd_gains");
  if (!gains || gains->type != YAML_MAPPING_NODE) {
    set_err(err, err_len, "robot.yaml: pd_gains: missing (the driver's hold needs them)");
    return -1;
  }
  double kp_default = NAN, kd_default = NAN;
  yaml_node_t *def = map_get(doc, gains, "default");
  if (def) {
    if (get_number(doc, def, "pd_gains.default", "kp", &kp_default, err, err_len) ||
        get_number(doc, def, "pd_gains.default", "kd", &kd_default, err, err_len))
      return -1;
  }
  for (int j = 0; j < r->joint_count; ++j) {
    r->joints[j].kp_hold = kp_default;
    r->joints[j].kd_hold = kd_default;
  }
  for (yaml_node_pair_t *p = gains->data.mapping.pairs.start; p < gains->data.mapping.pairs.top;
       ++p) {
    const char *name = scalar(yaml_document_get_node(doc, p->key));
    if (name && strcmp(name, "default") == 0) continue;
    const int j = name ? joint_index(r, name) : -1;
    if (j < 0) {
      set_err(err, err_len, "robot.yaml: pd_gains.%s: not a movable URDF joint",
              name ? name : "?");
      return -1;
    }
    char where[DRIVER_NAME_LEN + 16];
    snprintf(where, sizeof where, "pd_gains.%s", name);
    yaml_node_t *g = yaml_document_get_node(doc, p->value);
    if (get_number(doc, g, where, "kp", &r->joints[j].kp_hold, err, err_len) ||
        get_number(doc, g, where, "kd", &r->joints[j].kd_hold, err, err_len))
      return -1;
  }
  for (int j = 0; j < r->joint_count; ++j) {
    const driver_joint *d = &r->joints[j];
    if (!(d->kp_hold >= 0.0) || !(d->kd_hold >= 0.0)) {
      set_err(err, err_len, "robot.yaml: pd_gains: no gains >= 0 for joint '%s' (and no default)",
              d->name);
      return -1;
    }
  }
  return 0;
}

static int parse_config(driver_robot *r, const char *config_path, const char *urdf_override,
                        char *err, size_t err_len) {
  yaml_parser_t parser;
  yaml_document_t doc;
  if (!yaml_parser_initialize(&parser)) {
    set_err(err, err_len, "libyaml: cannot initialise the parser");
    return -1;
  }
  yaml_parser_set_input_string(&parser, (const unsigned char *)r->config_text,
                               strlen(r->config_text));
  if (!yaml_parser_load(&parser, &doc)) {
    set_err(err, err_len, "robot.yaml '%s' line %lu: %s", config_path,
            (unsigned long)parser.problem_mark.line + 1,
            parser.problem ? parser.problem : "YAML error");
    yaml_parser_delete(&parser);
    return -1;
  }
  yaml_parser_delete(&parser);
  int rc = -1;
  yaml_node_t *root = yaml_document_get_root_node(&doc);
  if (!root || root->type != YAML_MAPPING_NODE) {
    set_err(err, err_len, "robot.yaml '%s': not a mapping", config_path);
    goto done;
  }
  if (get_string(&doc, root, "", "name", r->name, sizeof r->name, err, err_len) ||
      get_string(&doc, root, "", "imu_frame", r->imu_frame, sizeof r->imu_frame, err, err_len))
    goto done;

  /* URDF: the command line wins, else the yaml's entry relative to the yaml's folder. */
  if (urdf_override) {
    snprintf(r->urdf_path, sizeof r->urdf_path, "%s", urdf_override);
  } else {
    char entry[2048];
    if (get_string(&doc, root, "", "urdf", entry, sizeof entry, err, err_len)) goto done;
    const char *slash = strrchr(config_path, '/');
    if (entry[0] == '/' || !slash)
      snprintf(r->urdf_path, sizeof r->urdf_path, "%s", entry);
    else
      snprintf(r->urdf_path, sizeof r->urdf_path, "%.*s/%s", (int)(slash - config_path),
               config_path, entry);
  }

  static const char *const side[2] = {"right", "left"};
  yaml_node_t *feet = map_get(&doc, root, "feet");
  for (int f = 0; f < 2; ++f) {
    yaml_node_t *foot = map_get(&doc, feet, side[f]);
    char where[64];
    snprintf(where, sizeof where, "feet.%s", side[f]);
    if (get_string(&doc, foot, where, "frame", r->feet[f].frame, sizeof r->feet[f].frame, err,
                   err_len))
      goto done;
    snprintf(where, sizeof where, "feet.%s.sole", side[f]);
    yaml_node_t *sole = map_get(&doc, foot, "sole");
    if (get_number(&doc, sole, where, "x_min", &r->feet[f].x_min, err, err_len) ||
        get_number(&doc, sole, where, "x_max", &r->feet[f].x_max, err, err_len) ||
        get_number(&doc, sole, where, "y_min", &r->feet[f].y_min, err, err_len) ||
        get_number(&doc, sole, where, "y_max", &r->feet[f].y_max, err, err_len) ||
        get_number(&doc, sole, where, "height", &r->feet[f].height, err, err_len))
      goto done;
  }
  yaml_node_t *contact = map_get(&doc, root, "contact");
  if (get_number(&doc, contact, "contact", "safety_margin", &r->safety_margin, err, err_len) ||
      get_number(&doc, contact, "contact", "friction_mu", &r->mu, err, err_len) ||
      get_number(&doc, contact, "contact", "torsional_mu", &r->mu_torsion, err, err_len))
    goto done;
  rc = 0;
done:
  if (rc == 0) {
    /* The joint tables need the URDF's joints: parse it first, then come back. */
    r->urdf_text = read_text_file(r->urdf_path, "URDF", err, err_len);
    if (!r->urdf_text || parse_urdf(r, err, err_len) ||
        read_joint_tables(&doc, root, r, err, err_len))
      rc = -1;
  }
  yaml_document_delete(&doc);
  return rc;
}

int driver_robot_load(const char *config_path, const char *urdf_path, driver_robot *robot,
                      char *err, size_t err_len) {
  memset(robot, 0, sizeof *robot);
  robot->config_text = read_text_file(config_path, "robot configuration", err, err_len);
  if (!robot->config_text) return -1;
  if (parse_config(robot, config_path, urdf_path, err, err_len)) {
    driver_robot_free(robot);
    return -1;
  }
  return 0;
}

void driver_robot_free(driver_robot *robot) {
  free(robot->urdf_text);
  free(robot->config_text);
  robot->urdf_text = NULL;
  robot->config_text = NULL;
}
