/* devices/map.c -- decoded events to one command per tick: per-axis
 * sensitivity, dead zone and curve, remap and inversion, dominant axis,
 * locks, device or world frame, button actions, clutch and e-stop, and
 * absolute pose streams turned into a twist toward the latest pose.
 *
 * Pure arithmetic on the events and the poses it is given: the same inputs
 * give the same twists bit for bit. */
#include "iso_dev_map.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "iso_dev_decode.h"

const char *const iso_dev_lock_names[] = {"none", "translation", "rotation", NULL};
const char *const iso_dev_frame_names[] = {"world", "device", NULL};
const char *const iso_dev_clutch_names[] = {"hold", "deadman", NULL};
const char *const iso_dev_action_names[] = {"none",       "clutch", "next_handle",
                                            "reset_pose", "record", NULL};
const char *const iso_dev_axis_names[] = {"tx", "ty", "tz", "rx", "ry", "rz", NULL};

void iso_dev_map_opts_default(iso_dev_map_opts *o)
{
    memset(o, 0, sizeof *o);
    o->full_scale = 350;
    for (int i = 0; i < 6; i++) {
        o->sensitivity[i] = i < 3 ? 0.1 : 0.5;
        o->dead_zone[i] = 0.05;
        o->curve[i] = 1;
        o->remap[i] = i;
    }
    o->button_action[0] = ISO_DEV_ACT_CLUTCH;
    o->button_action[1] = ISO_DEV_ACT_NEXT_HANDLE;
    o->n_handles = 1;
    o->pose_gain = 1;
    o->pose_scale = 1;
}

static const struct {
    const char *field;
    double lo, hi;        /* hi = INFINITY: no upper bound */
    int lo_open, hi_open; /* 1: the bound itself is out */
} ranges[] = {
    {"full_scale", 0, INFINITY, 1, 1}, {"sensitivity", 0, 1e6, 0, 0},
    {"dead_zone", 0, 0.99, 0, 0},      {"curve", 0.1, 10, 0, 0},
    {"pose_gain", 0, 1, 1, 0},         {"pose_scale", 0, INFINITY, 1, 1},
};

int iso_dev_map_check(const char *field, double v, char *why, size_t cap)
{
    for (size_t i = 0; i < sizeof ranges / sizeof ranges[0]; i++) {
        if (strcmp(ranges[i].field, field) != 0)
            continue;
        double lo = ranges[i].lo, hi = ranges[i].hi;
        int above = ranges[i].lo_open ? v > lo : v >= lo;
        int below = ranges[i].hi_open ? v < hi : v <= hi;
        if (above && below)
            return 0;
        if (isinf(hi))
            snprintf(why, cap, "expected a value %s %g, found %g",
                     ranges[i].lo_open ? ">" : ">=", lo, v);
        else
            snprintf(why, cap, "expected a value in %c%g, %g%c, found %g",
                     ranges[i].lo_open ? '(' : '[', lo, hi, ranges[i].hi_open ? ')' : ']', v);
        return -1;
    }
    snprintf(why, cap, "'%s' is not a numeric mapping option", field);
    return -1;
}

/* iso_dev_map_check for one option (axis >= 0: one of its six values). */
static int check_option(const char *field, int axis, double v, iso_err *err)
{
    char why[128];
    if (iso_dev_map_check(field, v, why, sizeof why) == 0)
        return ISO_OK;
    if (axis < 0)
        return iso_err_set(err, ISO_EINVAL, -1, "device mapping: %s: %s", field, why);
    return iso_err_set(err, ISO_EINVAL, -1, "device mapping: %s.%s: %s", field,
                       iso_dev_axis_names[axis], why);
}

int iso_dev_map_init(iso_dev_map *m, const iso_dev_map_opts *o, iso_err *err)
{
    memset(m, 0, sizeof *m);
    int rc;
    if (o->n_handles < 1 || o->n_handles > (int)ISO_DEV_MAX_HANDLES)
        return iso_err_set(err, ISO_EINVAL, -1, "device mapping: %d handles (must be 1 to %u)",
                           o->n_handles, ISO_DEV_MAX_HANDLES);
    if ((rc = check_option("full_scale", -1, o->full_scale, err)) ||
        (rc = check_option("pose_gain", -1, o->pose_gain, err)) ||
        (rc = check_option("pose_scale", -1, o->pose_scale, err)))
        return rc;
    for (int i = 0; i < 6; i++) {
        if (o->remap[i] < 0 || o->remap[i] > 5)
            return iso_err_set(err, ISO_EINVAL, -1,
                               "device mapping: axis %d remapped to %d (must be 0 to 5)", i,
                               o->remap[i]);
        if ((rc = check_option("sensitivity", i, o->sensitivity[i], err)) ||
            (rc = check_option("dead_zone", i, o->dead_zone[i], err)) ||
            (rc = check_option("curve", i, o->curve[i], err)))
            return rc;
    }
    for (int b = 0; b < 32; b++)
        if (o->button_action[b] > ISO_DEV_ACT_RECORD)
            return iso_err_set(err, ISO_EINVAL, -1, "device mapping: button %d action %d unknown",
                               b, o->button_action[b]);
    m->o = *o;
    for (unsigned i = 0; i < ISO_DEV_MAX_SOURCES; i++)
        m->stale_ns[i] = ISO_DEV_STALE_DEFAULT_NS;
    return ISO_OK;
}

int iso_dev_map_set_stale(iso_dev_map *m, int source, int64_t stale_ns, iso_err *err)
{
    if (source < 0 || source >= (int)ISO_DEV_MAX_SOURCES)
        return iso_err_set(err, ISO_EINVAL, -1, "device mapping: source %d (must be 0 to %u)",
                           source, ISO_DEV_MAX_SOURCES - 1);
    if (stale_ns < ISO_DEV_STALE_MIN_NS || stale_ns > ISO_DEV_STALE_MAX_NS)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "device mapping: source %d stale time %.3f ms (must be %g to %g ms)",
                           source, (double)stale_ns / 1e6, ISO_DEV_STALE_MIN_NS / 1e6,
                           ISO_DEV_STALE_MAX_NS / 1e6);
    m->stale_ns[source] = stale_ns;
    return ISO_OK;
}

int iso_dev_map_set_limits(iso_dev_map *m, int source, double speed, double turn, iso_err *err)
{
    if (source < 0 || source >= (int)ISO_DEV_MAX_SOURCES)
        return iso_err_set(err, ISO_EINVAL, -1, "device mapping: source %d (must be 0 to %u)",
                           source, ISO_DEV_MAX_SOURCES - 1);
    if (!(speed >= 0) || !(turn >= 0) || isinf(speed) || isinf(turn))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "device mapping: source %d: speed %g and turn %g must be finite and "
                           ">= 0",
                           source, speed, turn);
    m->max_speed[source] = speed;
    m->max_turn[source] = turn;
    return ISO_OK;
}

int iso_dev_map_set_workspace(iso_dev_map *m, int source, double radius, iso_err *err)
{
    if (source < 0 || source >= (int)ISO_DEV_MAX_SOURCES)
        return iso_err_set(err, ISO_EINVAL, -1, "device mapping: source %d (must be 0 to %u)",
                           source, ISO_DEV_MAX_SOURCES - 1);
    if (!(radius >= 0) || isinf(radius))
        return iso_err_set(err, ISO_EINVAL, -1,
                           "device mapping: source %d: workspace %g must be finite and >= 0",
                           source, radius);
    m->workspace[source] = radius;
    return ISO_OK;
}

/* Whether the pose v (position v[0..2] times scale, rotation vector
 * v[3..5]) would put handle h's centre farther than radius from where it
 * rests: |R c + p - c| (radius 0: never). */
static int beyond_workspace(const iso_dev_map *m, int h, const double v[6], double scale,
                            double radius)
{
    if (!(radius > 0))
        return 0;
    const double *c = m->centre[h >= 0 && h < (int)ISO_DEV_MAX_HANDLES ? h : 0];
    iso_twist rv = {{v[3], v[4], v[5]}, {0, 0, 0}};
    iso_pose T;
    iso_twist_exp(&rv, 1.0, &T);
    for (int i = 0; i < 3; i++)
        T.p[i] = v[i] * scale;
    double at[3], d2 = 0;
    iso_pose_apply(&T, c, at);
    for (int i = 0; i < 3; i++)
        d2 += (at[i] - c[i]) * (at[i] - c[i]);
    return !(d2 <= radius * radius); /* NaN is beyond too */
}

void iso_dev_map_set_centre(iso_dev_map *m, int h, const double c[3])
{
    if (h >= 0 && h < (int)ISO_DEV_MAX_HANDLES)
        memcpy(m->centre[h], c, sizeof m->centre[h]);
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* (v, w) at the handle's centre c, in world axes, to the world twist whose
 * velocity at y is v0 + w × y: v0 = v − w × c. */
static void twist_about(const double v[3], const double w[3], const double c[3], iso_twist *out)
{
    double wc[3];
    cross(w, c, wc);
    for (int i = 0; i < 3; i++) {
        out->w[i] = w[i];
        out->v[i] = v[i] - wc[i];
    }
}

void iso_dev_map_axes(const iso_dev_map_opts *o, const int16_t axes[6], const iso_pose *g,
                      iso_twist *out)
{
    double u[6];
    for (int i = 0; i < 6; i++) {
        double x = axes[o->remap[i]] / o->full_scale;
        if (o->invert[i])
            x = -x;
        double a = fabs(x) > 1 ? 1 : fabs(x), dz = o->dead_zone[i];
        double s = a <= dz ? 0 : pow((a - dz) / (1 - dz), o->curve[i]);
        u[i] = (x < 0 ? -s : s) * o->sensitivity[i];
    }
    if (o->dominant) {
        /* Compare shaped deflections, not velocities: metres and radians
         * do not compare. Ties go to the lower axis. */
        int best = 0;
        double bm = -1;
        for (int i = 0; i < 6; i++) {
            double d = o->sensitivity[i] != 0 ? fabs(u[i] / o->sensitivity[i]) : 0;
            if (d > bm) {
                bm = d;
                best = i;
            }
        }
        for (int i = 0; i < 6; i++)
            if (i != best)
                u[i] = 0;
    }
    if (o->lock == ISO_DEV_LOCK_TRANSLATION)
        u[3] = u[4] = u[5] = 0;
    else if (o->lock == ISO_DEV_LOCK_ROTATION)
        u[0] = u[1] = u[2] = 0;
    double v[3] = {u[0], u[1], u[2]}, w[3] = {u[3], u[4], u[5]};
    if (o->frame == ISO_DEV_FRAME_DEVICE) {
        iso_pose_rotate(g, u, v);
        iso_pose_rotate(g, u + 3, w);
    }
    twist_about(v, w, g->p, out);
}

/* The screw xi from g to a target pose over one unit of time: the target's
 * rotation is the exponential of its rotation vector tgt[3..5], its
 * position tgt[0..2] times scale. Fails on a half-turn error, which has no
 * unique screw. */
static int screw_to(const double tgt[6], double scale, const iso_pose *g, iso_twist *xi)
{
    iso_twist rv = {{tgt[3], tgt[4], tgt[5]}, {0, 0, 0}};
    iso_pose T;
    iso_twist_exp(&rv, 1.0, &T);
    for (int i = 0; i < 3; i++)
        T.p[i] = tgt[i] * scale;
    return iso_twist_between(g, &T, xi, NULL);
}

static void twist_scaled(const iso_twist *xi, double k, iso_twist *out)
{
    for (int i = 0; i < 3; i++) {
        out->w[i] = k * xi->w[i];
        out->v[i] = k * xi->v[i];
    }
}

/* The twist that carries g toward the target pose T in one tick of dt:
 * M = T g⁻¹, ξ = gain · log(M) / dt. A half-turn error has no unique screw:
 * the handle then holds still this tick (the next sample decides). */
static void twist_toward(const iso_dev_map_opts *o, const double tgt[6], const iso_pose *g,
                         double dt, iso_twist *out)
{
    memset(out, 0, sizeof *out);
    iso_twist xi;
    if (!(dt > 0) || screw_to(tgt, o->pose_scale, g, &xi) != ISO_OK)
        return;
    twist_scaled(&xi, o->pose_gain / dt, out);
}

/* A view's target: the twist that reaches it in this tick, along the same
 * screw but slower when it would move the handle's centre c (where it is
 * now) faster than speed or turn it faster than turn (0: no bound). The
 * target is in scene units: no pose_scale, no pose_gain (the bounds give
 * the smoothness, and the handle ends on the target). */
static void twist_to_target(const double tgt[6], const iso_pose *g, const double c[3], double dt,
                            double speed, double turn, iso_twist *out)
{
    memset(out, 0, sizeof *out);
    iso_twist xi;
    if (!(dt > 0) || screw_to(tgt, 1.0, g, &xi) != ISO_OK)
        return;
    double vel[3];
    iso_twist_velocity(&xi, c, vel); /* the centre's travel over the whole step */
    double d = sqrt(vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]);
    double a = sqrt(xi.w[0] * xi.w[0] + xi.w[1] * xi.w[1] + xi.w[2] * xi.w[2]);
    double k = 1.0 / dt;
    if (speed > 0 && d > speed * dt)
        k = fmin(k, speed / d);
    if (turn > 0 && a > turn * dt)
        k = fmin(k, turn / a);
    twist_scaled(&xi, k, out);
}

static void press(iso_dev_map *m, uint32_t before, uint32_t after, iso_dev_tick *out)
{
    for (int b = 0; b < 32; b++) {
        uint32_t bit = (uint32_t)1 << b;
        if ((after & bit) && !(before & bit)) {
            int act = m->o.button_action[b];
            if (act != ISO_DEV_ACT_NONE)
                out->actions |= (uint32_t)1 << act;
            if (act == ISO_DEV_ACT_NEXT_HANDLE)
                m->active = (m->active + 1) % m->o.n_handles;
        }
    }
}

static int clutch_from_buttons(const iso_dev_map *m, uint32_t b)
{
    for (int i = 0; i < 32; i++)
        if ((b & ((uint32_t)1 << i)) && m->o.button_action[i] == ISO_DEV_ACT_CLUTCH)
            return 1;
    return 0;
}

/* Phase 1: the tick's events, in order, into each source's state; what
 * they press goes into out. Returns the GPIO clutch after them. One event
 * at a time, as they came, because a source's state is its last word: a
 * button pressed and released within one tick still counts as pressed,
 * and a GONE clears what its source said before it. */
static uint8_t apply_events(iso_dev_map *m, const iso_dev_event *ev, size_t n, iso_dev_tick *out)
{
    uint8_t gpio_clutch = m->clutch & 2;
    for (size_t i = 0; i < n; i++) {
        const iso_dev_event *e = &ev[i];
        if (e->source >= ISO_DEV_MAX_SOURCES)
            continue;
        iso_dev_map_src *s = &m->src[e->source];
        uint32_t bit = (uint32_t)1 << e->source;
        switch (e->kind) {
        case ISO_DEV_EV_AXES: memcpy(s->axes, e->axes, sizeof s->axes); break;
        case ISO_DEV_EV_BUTTONS:
            press(m, s->buttons, e->buttons, out);
            s->buttons = e->buttons;
            break;
        case ISO_DEV_EV_POSE:
            if (beyond_workspace(m, m->active, e->v, m->o.pose_scale, m->workspace[e->source])) {
                m->far[e->source]++;
                break;
            }
            memcpy(s->v, e->v, sizeof s->v);
            s->has_pose = 1;
            s->has_twist = s->has_target = 0;
            break;
        case ISO_DEV_EV_TWIST:
            memcpy(s->v, e->v, sizeof s->v);
            s->has_twist = 1;
            s->has_pose = s->has_target = 0;
            s->t_twist = e->t_ns;
            break;
        case ISO_DEV_EV_TARGET:
            if (beyond_workspace(m, e->line, e->v, 1.0, m->workspace[e->source])) {
                m->far[e->source]++;
                break;
            }
            memcpy(s->v, e->v, sizeof s->v);
            s->has_target = 1;
            s->handle = e->line;
            s->has_pose = s->has_twist = 0;
            s->t_twist = e->t_ns;
            break;
        case ISO_DEV_EV_RELEASE: s->has_target = 0; break;
        case ISO_DEV_EV_GPIO:
            if (e->line == ISO_DEV_GPIO_ESTOP) {
                s->estop_line = 1;
                s->estop = e->level;
            } else if (e->line == ISO_DEV_GPIO_CLUTCH) {
                gpio_clutch = e->level ? 2 : 0;
                if (e->level)
                    out->actions |= (uint32_t)1 << ISO_DEV_ACT_CLUTCH;
            }
            break;
        case ISO_DEV_EV_GONE: {
            /* Its handles hold still until it is back; its e-stop line,
             * if it had one, counts as pressed until it reads released. */
            uint8_t line = s->estop_line;
            memset(s, 0, sizeof *s);
            s->estop_line = s->estop = line;
            m->gone |= bit;
            break;
        }
        case ISO_DEV_EV_BACK: m->gone &= ~bit; break;
        default: break;
        }
    }
    return gpio_clutch;
}

/* Phase 2: the sources together at now_ns: stale streams, buttons, the
 * e-stop and the clutch, into out. Returns 1 when the handles hold. After
 * every event of the tick, because these are decided over all sources at
 * once (any source's e-stop stops every handle, any source's button can
 * be the clutch), and before any twist, because they decide whether there
 * is one. Staleness is measured on now_ns, the stream time, so that a
 * replay decides it the same. */
static int sum_sources(iso_dev_map *m, uint8_t gpio_clutch, int64_t now_ns, iso_dev_tick *out)
{
    /* Strictly past the stale time: a sample exactly stale_ns old still counts. */
    for (unsigned i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
        iso_dev_map_src *s = &m->src[i];
        s->stale = (s->has_twist || s->has_target) && now_ns - s->t_twist > m->stale_ns[i];
        if (s->stale)
            out->stale |= (uint32_t)1 << i;
        else if (s->has_target && !(m->gone & ((uint32_t)1 << i)))
            out->targeting |= (uint32_t)1 << i;
    }
    uint32_t buttons = 0;
    m->estop = 0;
    for (unsigned i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
        buttons |= m->src[i].buttons;
        m->estop |= m->src[i].estop;
    }
    if (m->estop) /* what was commanded before a stop is not resumed after it */
        for (unsigned i = 0; i < ISO_DEV_MAX_SOURCES; i++)
            m->src[i].has_target = 0;
    m->clutch = (uint8_t)(gpio_clutch | clutch_from_buttons(m, buttons));
    out->active = m->active;
    out->clutch = m->clutch != 0;
    out->estop = m->estop;
    out->buttons = buttons;
    out->gone = m->gone;
    int hold = m->o.clutch_is_deadman ? !out->clutch : out->clutch;
    if (m->estop || hold)
        out->targeting = 0;
    return m->estop || hold;
}

/* Phase 3: each live source's twist, added to its handle's; only when
 * phase 2 found the handles free. Added, not chosen, so that two devices
 * on one handle combine; a source gone or stale adds nothing, so that its
 * last twist never keeps driving a handle. */
static void add_twists(iso_dev_map *m, double dt_s, const iso_pose *poses, iso_dev_tick *out)
{
    for (unsigned i = 0; i < ISO_DEV_MAX_SOURCES; i++) {
        const iso_dev_map_src *s = &m->src[i];
        if ((m->gone & ((uint32_t)1 << i)) || s->stale)
            continue;
        /* a view's target names its handle; everything else drives the active one */
        int h = s->has_target ? s->handle : m->active;
        if (h >= m->o.n_handles) {
            out->targeting &= ~((uint32_t)1 << i);
            continue;
        }
        const iso_pose *g = &poses[h];
        iso_pose gc = *g; /* rotations turn about the handle's centre, where it is now */
        iso_pose_apply(g, m->centre[h], gc.p);
        iso_twist x;
        if (s->has_target) {
            twist_to_target(s->v, g, gc.p, dt_s, m->max_speed[i], m->max_turn[i], &x);
        } else if (s->has_pose) {
            twist_toward(&m->o, s->v, g, dt_s, &x);
        } else if (s->has_twist) {
            double v[3], w[3];
            for (int k = 0; k < 3; k++) {
                v[k] = s->v[k] * m->o.pose_scale;
                w[k] = s->v[3 + k];
            }
            twist_about(v, w, gc.p, &x);
        } else {
            iso_dev_map_axes(&m->o, s->axes, &gc, &x);
        }
        iso_twist *t = &out->twist[h];
        for (int k = 0; k < 3; k++) {
            t->w[k] += x.w[k];
            t->v[k] += x.v[k];
        }
    }
}

void iso_dev_map_tick(iso_dev_map *m, const iso_dev_event *ev, size_t n, int64_t now_ns,
                      double dt_s, const iso_pose *poses, iso_dev_tick *out)
{
    memset(out, 0, sizeof *out);
    out->t_ns = now_ns;
    out->n_handles = m->o.n_handles;
    uint8_t gpio_clutch = apply_events(m, ev, n, out);
    if (!sum_sources(m, gpio_clutch, now_ns, out))
        add_twists(m, dt_s, poses, out);
}
