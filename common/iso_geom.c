/* common/iso_geom.c -- rigid poses and twists (iso_geom.h). */
#include "iso_geom.h"

#include <math.h>
#include <string.h>

void iso_pose_identity(iso_pose *g)
{
    memset(g, 0, sizeof *g);
    g->R[0] = g->R[4] = g->R[8] = 1.0;
}

void iso_pose_compose(const iso_pose *a, const iso_pose *b, iso_pose *g)
{
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            g->R[3 * i + j] = a->R[3 * i] * b->R[j] + a->R[3 * i + 1] * b->R[3 + j] +
                              a->R[3 * i + 2] * b->R[6 + j];
        g->p[i] =
            a->R[3 * i] * b->p[0] + a->R[3 * i + 1] * b->p[1] + a->R[3 * i + 2] * b->p[2] + a->p[i];
    }
}

void iso_pose_apply(const iso_pose *g, const double x[3], double y[3])
{
    for (int i = 0; i < 3; i++)
        y[i] = g->R[3 * i] * x[0] + g->R[3 * i + 1] * x[1] + g->R[3 * i + 2] * x[2] + g->p[i];
}

void iso_pose_rotate(const iso_pose *g, const double x[3], double y[3])
{
    for (int i = 0; i < 3; i++)
        y[i] = g->R[3 * i] * x[0] + g->R[3 * i + 1] * x[1] + g->R[3 * i + 2] * x[2];
}

void iso_pose_about(const double R[9], const double c[3], const double t[3], iso_pose *g)
{
    memcpy(g->R, R, sizeof g->R);
    for (int i = 0; i < 3; i++) {
        double rc = R[3 * i] * c[0] + R[3 * i + 1] * c[1] + R[3 * i + 2] * c[2];
        g->p[i] = c[i] + (t ? t[i] : 0.0) - rc;
    }
}

void iso_pose_to_matrix(const iso_pose *g, double M[16])
{
    memset(M, 0, 16 * sizeof *M);
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            M[4 * i + j] = g->R[3 * i + j];
        M[4 * i + 3] = g->p[i];
    }
    M[15] = 1.0;
}

void iso_twist_velocity(const iso_twist *xi, const double y[3], double vel[3])
{
    vel[0] = xi->v[0] + xi->w[1] * y[2] - xi->w[2] * y[1];
    vel[1] = xi->v[1] + xi->w[2] * y[0] - xi->w[0] * y[2];
    vel[2] = xi->v[2] + xi->w[0] * y[1] - xi->w[1] * y[0];
}

/* Cross-product matrix [w]x, row-major: [w]x y = w × y. */
static void cross_matrix(const double w[3], double W[9])
{
    W[0] = 0;
    W[1] = -w[2];
    W[2] = w[1];
    W[3] = w[2];
    W[4] = 0;
    W[5] = -w[0];
    W[6] = -w[1];
    W[7] = w[0];
    W[8] = 0;
}

static void mat3_mul(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* exp([w]x) = I + a W + b W², and V(w) = I + b W + c W², the matrix that
 * maps the twist's v to the screw's translation. Series near θ = 0 keep
 * full precision where the closed forms cancel. */
static void exp_coefficients(double theta, double *a, double *b, double *c)
{
    double t2 = theta * theta;
    if (theta < 1e-4) {
        *a = 1 - t2 / 6;
        *b = 0.5 - t2 / 24;
        *c = 1.0 / 6 - t2 / 120;
    } else {
        *a = sin(theta) / theta;
        *b = (1 - cos(theta)) / t2;
        *c = (theta - sin(theta)) / (t2 * theta);
    }
}

void iso_twist_exp(const iso_twist *xi, double t, iso_pose *g)
{
    double w[3] = {t * xi->w[0], t * xi->w[1], t * xi->w[2]};
    double v[3] = {t * xi->v[0], t * xi->v[1], t * xi->v[2]};
    double theta = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    double a, b, c, W[9], W2[9];
    exp_coefficients(theta, &a, &b, &c);
    cross_matrix(w, W);
    mat3_mul(W, W, W2);
    double V[9];
    for (int i = 0; i < 9; i++) {
        double id = (i % 4 == 0) ? 1.0 : 0.0;
        g->R[i] = id + a * W[i] + b * W2[i];
        V[i] = id + b * W[i] + c * W2[i];
    }
    for (int i = 0; i < 3; i++)
        g->p[i] = V[3 * i] * v[0] + V[3 * i + 1] * v[1] + V[3 * i + 2] * v[2];
}

void iso_rotation_quaternion(const double R[9], double q[4])
{
    double tr = R[0] + R[4] + R[8];
    if (tr > R[0] && tr > R[4] && tr > R[8]) {
        double s = 2 * sqrt(1 + tr);
        q[0] = s / 4;
        q[1] = (R[7] - R[5]) / s;
        q[2] = (R[2] - R[6]) / s;
        q[3] = (R[3] - R[1]) / s;
    } else if (R[0] >= R[4] && R[0] >= R[8]) {
        double s = 2 * sqrt(1 + R[0] - R[4] - R[8]);
        q[0] = (R[7] - R[5]) / s;
        q[1] = s / 4;
        q[2] = (R[1] + R[3]) / s;
        q[3] = (R[2] + R[6]) / s;
    } else if (R[4] >= R[8]) {
        double s = 2 * sqrt(1 + R[4] - R[0] - R[8]);
        q[0] = (R[2] - R[6]) / s;
        q[1] = (R[1] + R[3]) / s;
        q[2] = s / 4;
        q[3] = (R[5] + R[7]) / s;
    } else {
        double s = 2 * sqrt(1 + R[8] - R[0] - R[4]);
        q[0] = (R[3] - R[1]) / s;
        q[1] = (R[2] + R[6]) / s;
        q[2] = (R[5] + R[7]) / s;
        q[3] = s / 4;
    }
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (q[0] < 0)
        n = -n; /* the rotation angle in [0, π] */
    for (int i = 0; i < 4; i++)
        q[i] /= n;
}

int iso_twist_from_matrix(const double M[16], iso_twist *xi, iso_err *err)
{
    double R[9] = {M[0], M[1], M[2], M[4], M[5], M[6], M[8], M[9], M[10]};
    double p[3] = {M[3], M[7], M[11]};
    double q[4];
    iso_rotation_quaternion(R, q);
    double sn = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double theta = 2 * atan2(sn, q[0]);
    if (theta > 3.14159265358979323846 - 1e-9)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "a handle rotation of 180 degrees has no unique screw path "
                           "(its direction is ambiguous); split it into two motions");
    double w[3] = {0, 0, 0};
    if (sn > 0)
        for (int i = 0; i < 3; i++)
            w[i] = theta * q[i + 1] / sn;
    /* v = V(w)^{-1} p, V^{-1} = I − W/2 + d W², d = (1 − θ sinθ / (2(1 − cosθ))) / θ². */
    double d = theta < 1e-4 ? 1.0 / 12 + theta * theta / 720
                            : (1 - theta * sin(theta) / (2 * (1 - cos(theta)))) / (theta * theta);
    double W[9], W2[9];
    cross_matrix(w, W);
    mat3_mul(W, W, W2);
    for (int i = 0; i < 3; i++) {
        xi->w[i] = w[i];
        xi->v[i] = 0;
        for (int j = 0; j < 3; j++) {
            double id = i == j ? 1.0 : 0.0;
            xi->v[i] += (id - 0.5 * W[3 * i + j] + d * W2[3 * i + j]) * p[j];
        }
    }
    return ISO_OK;
}

int iso_twist_between(const iso_pose *a, const iso_pose *b, iso_twist *xi, iso_err *err)
{
    double M[16] = {0};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            double s = 0;
            for (int q = 0; q < 3; q++)
                s += b->R[3 * i + q] * a->R[3 * j + q]; /* R_b R_aᵀ */
            M[4 * i + j] = s;
        }
    }
    for (int i = 0; i < 3; i++) {
        double s = b->p[i];
        for (int j = 0; j < 3; j++)
            s -= M[4 * i + j] * a->p[j];
        M[4 * i + 3] = s;
    }
    M[15] = 1;
    return iso_twist_from_matrix(M, xi, err);
}
