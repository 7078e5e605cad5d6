/* Test helpers for the RGL reader: see rgl_ref.h. */
#include "rgl_ref.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

/* ---- a tensor_file writer ------------------------------------------------- */

static void put(FILE *fp, uint64_t v, int n) {
    for (int k = 0; k < n; k++)
        fputc((int)(v >> (8 * k)) & 0xff, fp);
}

static uint64_t wcount(const wfield_t *f) {
    uint64_t n = 1;
    for (int d = 0; d < f->ndim; d++)
        n *= f->shape[d];
    return n;
}

void write_tensor(const char *path, const wfield_t *f, int nf) {
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (!fp) return;
    uint64_t head = 18;
    for (int k = 0; k < nf; k++)
        head += 2 + strlen(f[k].name) + 2 + 1 + 8 + 8 * (uint64_t)f[k].ndim;
    fwrite("tensor_file\0", 1, 12, fp);
    put(fp, 1, 1);
    put(fp, 0, 1);
    put(fp, (uint64_t)nf, 4);
    uint64_t off = (head + 7) & ~(uint64_t)7;
    for (int k = 0; k < nf; k++) {
        put(fp, strlen(f[k].name), 2);
        fwrite(f[k].name, 1, strlen(f[k].name), fp);
        put(fp, (uint64_t)f[k].ndim, 2);
        put(fp, f[k].dtype, 1);
        put(fp, off, 8);
        for (int d = 0; d < f[k].ndim; d++)
            put(fp, f[k].shape[d], 8);
        off += (wcount(&f[k]) * (f[k].dtype == 1 ? 1 : 4) + 7) & ~(uint64_t)7;
    }
    for (uint64_t p = head; p % 8; p++)
        fputc(0, fp);
    for (int k = 0; k < nf; k++) {
        uint64_t bytes = wcount(&f[k]) * (f[k].dtype == 1 ? 1 : 4);
        if (f[k].dtype == 1)
            fwrite(f[k].data, 1, bytes, fp);
        else
            for (uint64_t i = 0; i < wcount(&f[k]); i++) {
                uint32_t u;
                memcpy(&u, (const float *)f[k].data + i, 4);
                put(fp, u, 4);
            }
        for (; bytes % 8; bytes++)
            fputc(0, fp);
    }
    fclose(fp);
}

/* ---- the material, as the reference sees it --------------------------------- */

double rnd(unsigned long long *s) { return sb_rand01(s); }

void mat_random(mat_t *m, unsigned long long seed, int nphi, float phi0, float phi1) {
    unsigned long long s = seed;
    m->nphi = nphi;
    m->ntheta = 5;
    m->vw = 16, m->vh = 12, m->cw = 9, m->ch = 7, m->nw = 20, m->nh = 2;
    m->chans = m->chans ? m->chans : 3;
    for (int k = 0; k < m->ntheta; k++)
        m->theta[k] = (float)(k * (PI / 2) / (m->ntheta - 1) * (0.9 + 0.1 * k / (m->ntheta - 1.0)));
    for (int k = 0; k < nphi; k++)
        m->phi[k] = nphi == 1 ? 0.f : phi0 + (phi1 - phi0) * (float)k / (float)(nphi - 1);
    size_t sl = (size_t)nphi * (size_t)m->ntheta;
    m->vndf = malloc(sl * (size_t)(m->vw * m->vh) * sizeof(float));
    m->col = malloc(sl * (size_t)(m->chans * m->cw * m->ch) * sizeof(float));
    m->ndf = malloc((size_t)(m->nw * m->nh) * sizeof(float));
    m->sigma = malloc((size_t)(m->nw * m->nh) * sizeof(float));
    for (size_t i = 0; i < sl * (size_t)(m->vw * m->vh); i++)
        m->vndf[i] = (float)(0.05 + rnd(&s));
    for (size_t i = 0; i < sl * (size_t)(m->chans * m->cw * m->ch); i++)
        m->col[i] = (float)(rnd(&s) * 2 - 0.2); /* some negative: clamped */
    for (int i = 0; i < m->nw * m->nh; i++) {
        m->ndf[i] = (float)(0.1 + 3 * rnd(&s));
        m->sigma[i] = (float)(0.3 + rnd(&s));
    }
    m->jacobian = 1;
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 8; k++)
            m->cw3[c][k] = c == k;
}

void mat_free(mat_t *m) {
    free(m->norm);
    free(m->vndf);
    free(m->col);
    free(m->ndf);
    free(m->sigma);
}

void mat_write(const char *path, const mat_t *m, const float *wl) {
    unsigned char jac = (unsigned char)m->jacobian;
    const char *desc = "synthetic test material";
    uint64_t np = (uint64_t)m->nphi, nt = (uint64_t)m->ntheta;
    wfield_t f[9] = {
        {"description", 1, 1, {strlen(desc)}, desc},
        {"phi_i", 10, 1, {np}, m->phi},
        {"theta_i", 10, 1, {nt}, m->theta},
        {"ndf", 10, 2, {(uint64_t)m->nh, (uint64_t)m->nw}, m->ndf},
        {"sigma", 10, 2, {(uint64_t)m->nh, (uint64_t)m->nw}, m->sigma},
        {"vndf", 10, 4, {np, nt, (uint64_t)m->vh, (uint64_t)m->vw}, m->vndf},
        {wl ? "spectra" : "rgb", 10, 5, {np, nt, (uint64_t)m->chans, (uint64_t)m->ch, (uint64_t)m->cw}, m->col},
        {"jacobian", 1, 1, {1}, &jac},
        {"wavelengths", 10, 1, {(uint64_t)m->chans}, wl},
    };
    write_tensor(path, f, wl ? 9 : 8);
}

/* ---- the reference evaluation ------------------------------------------------ */

/* Bilinear texture lookup on nodes k/(n-1), position clamped. */
double tex(const float *t, int w, int h, double x, double y) {
    x = (x < 0 ? 0 : x > 1 ? 1 : x) * (w - 1);
    y = (y < 0 ? 0 : y > 1 ? 1 : y) * (h - 1);
    int i = (int)x < w - 2 ? (int)x : w - 2, j = (int)y < h - 2 ? (int)y : h - 2;
    double a = x - i, b = y - j;
    return (1 - a) * (1 - b) * t[j * w + i] + a * (1 - b) * t[j * w + i + 1] + (1 - a) * b * t[(j + 1) * w + i] +
           a * b * t[(j + 1) * w + i + 1];
}

/* Integral of g over [a, b] by 2-point Gauss-Legendre on each piece between
 * the nodes k/(n-1) (exact for the piecewise cubic integrands used here). */
static double integrate(double (*g)(const void *, double), const void *ctx, int n, double a, double b) {
    double sum = 0, r = 0.5773502691896257645;
    for (int k = 0; k + 1 < n; k++) {
        double lo = (double)k / (n - 1), hi = (double)(k + 1) / (n - 1);
        if (lo < a) lo = a;
        if (hi > b) hi = b;
        if (hi <= lo) continue;
        double c = 0.5 * (lo + hi), d = 0.5 * (hi - lo);
        sum += d * (g(ctx, c - d * r) + g(ctx, c + d * r));
    }
    return sum;
}

/* The mixed, per-slice normalised density of the vndf slices. */
typedef struct dens {
    const mat_t *m;
    int idx[4];
    double wt[4], y; /* y: fixed row for row integrals */
} dens_t;

static double dens_at(const dens_t *d, double x, double y) {
    double v = 0;
    for (int q = 0; q < 4; q++)
        if (d->wt[q] != 0)
            v += d->wt[q] / d->m->norm[d->idx[q]] *
                 tex(d->m->vndf + (size_t)d->idx[q] * (size_t)(d->m->vw * d->m->vh), d->m->vw, d->m->vh, x, y);
    return v;
}
static double one_x(const void *c, double x) {
    const dens_t *d = c;
    return tex(d->m->vndf + (size_t)d->idx[0] * (size_t)(d->m->vw * d->m->vh), d->m->vw, d->m->vh, x, d->y);
}
static double dens_x(const void *c, double x) {
    const dens_t *d = c;
    return dens_at(d, x, d->y);
}
static double row_total(const void *c, double y) {
    dens_t d = *(const dens_t *)c;
    d.y = y;
    return integrate(dens_x, &d, d.m->vw, 0, 1);
}

/* Each vndf slice's integral over the unit square, by quadrature. */
void mat_norms(mat_t *m) {
    int sl = m->nphi * m->ntheta;
    m->norm = malloc((size_t)sl * sizeof(double));
    for (int k = 0; k < sl; k++) {
        dens_t one = {m, {k, 0, 0, 0}, {1, 0, 0, 0}, 0};
        double sum = 0, r = 0.5773502691896257645;
        for (int j = 0; j + 1 < m->vh; j++) {
            double lo = (double)j / (m->vh - 1), hi = (double)(j + 1) / (m->vh - 1), c = 0.5 * (lo + hi),
                   d = 0.5 * (hi - lo);
            one.y = c - d * r;
            sum += d * integrate(one_x, &one, m->vw, 0, 1);
            one.y = c + d * r;
            sum += d * integrate(one_x, &one, m->vw, 0, 1);
        }
        m->norm[k] = sum;
    }
}

/* Slice and weight along one sorted axis, as "linear between nodes,
 * constant beyond the ends". */
static void axis(const float *x, int n, double p, int *i, double *w) {
    if (n == 1 || p <= x[0]) {
        *i = 0, *w = 0;
        return;
    }
    if (p >= x[n - 1]) {
        *i = n - 2, *w = 1;
        return;
    }
    int k = 0;
    while (!(p <= x[k + 1]))
        k++;
    *i = k, *w = (p - x[k]) / (x[k + 1] - x[k]);
}

/* f_r for light l, view v (both above the horizon). */
void ref_eval(const mat_t *m, const double l_in[3], const double v_in[3], double rgb[3], double s[2], double *jac_out) {
    double l[3] = {l_in[0], l_in[1], l_in[2]}, v[3] = {v_in[0], v_in[1], v_in[2]};
    double span = m->phi[m->nphi - 1] - m->phi[0];
    int red = m->nphi > 2 ? (int)lround(2 * PI / span) : 1;
    if (red == 2 && !signbit(v[1])) /* keep y <= 0: rotate by pi */
        l[0] = -l[0], l[1] = -l[1], v[0] = -v[0], v[1] = -v[1];
    if (red == 4) { /* the quadrant x <= 0, y <= 0 */
        if (!signbit(v[0])) l[0] = -l[0], v[0] = -v[0];
        if (!signbit(v[1])) l[1] = -l[1], v[1] = -v[1];
    }
    double h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]}, hn = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    double tv = atan2(hypot(v[0], v[1]), v[2]), pv = atan2(v[1], v[0]);
    double tm = atan2(hypot(h[0], h[1]), h[2]), pm = atan2(h[1] / hn, h[0] / hn);
    double dphi = m->nphi <= 2 ? pm - pv : pm;
    double um[2] = {sqrt(tm / (PI / 2)), (dphi + PI) / (2 * PI)};
    um[1] -= floor(um[1]);
    double uv[2] = {sqrt(tv / (PI / 2)), (pv + PI) / (2 * PI)};
    int ip, it;
    double wp, wt;
    axis(m->phi, m->nphi, pv, &ip, &wp);
    axis(m->theta, m->ntheta, tv, &it, &wt);
    dens_t d = {m, {0}, {0}, 0};
    int dp = m->nphi > 1, dt = m->ntheta > 1;
    for (int q = 0; q < 4; q++) {
        int a = q >> 1, b = q & 1;
        d.idx[q] = (ip + a * dp) * m->ntheta + it + b * dt;
        d.wt[q] = (a ? wp : 1 - wp) * (b ? wt : 1 - wt);
    }
    double Y = integrate(row_total, &d, m->vh, 0, um[1]);
    d.y = um[1];
    double X = integrate(dens_x, &d, m->vw, 0, um[0]) / integrate(dens_x, &d, m->vw, 0, 1);
    double jac =
        m->jacobian ? tex(m->ndf, m->nw, m->nh, um[0], um[1]) / (4 * tex(m->sigma, m->nw, m->nh, uv[0], uv[1])) : 1;
    if (s) s[0] = X, s[1] = Y;
    if (jac_out) *jac_out = jac;
    for (int c = 0; c < 3; c++) {
        double val = 0;
        for (int k = 0; k < m->chans; k++) {
            if (m->cw3[c][k] == 0) continue;
            double ch = 0;
            for (int q = 0; q < 4; q++)
                if (d.wt[q] != 0)
                    ch += d.wt[q] *
                          tex(m->col + ((size_t)d.idx[q] * (size_t)m->chans + (size_t)k) * (size_t)(m->cw * m->ch),
                              m->cw, m->ch, X, Y);
            val += m->cw3[c][k] * ch;
        }
        val *= jac;
        rgb[c] = val > 0 ? val / l[2] : 0;
    }
}

/* The test's own reader of the fields the reference needs. */
int load_real(const char *path, mat_t *m) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return 0;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)n);
    int ok = b && fread(b, 1, (size_t)n, fp) == (size_t)n;
    fclose(fp);
    memset(m, 0, sizeof *m);
    m->chans = 3;
    for (int i = 0; i < 3; i++)
        m->cw3[i][i] = 1;
    uint32_t count = b[14] | b[15] << 8 | (uint32_t)b[16] << 16 | (uint32_t)b[17] << 24;
    size_t p = 18;
    for (uint32_t k = 0; ok && k < count; k++) {
        size_t len = b[p] | (size_t)b[p + 1] << 8;
        char name[64] = {0};
        memcpy(name, b + p + 2, len < 63 ? len : 63);
        p += 2 + len;
        int nd = b[p] | b[p + 1] << 8, dtype = b[p + 2];
        uint64_t off = 0, shape[5] = {0}, cnt = 1;
        for (int q = 7; q >= 0; q--)
            off = off << 8 | b[p + 3 + q];
        p += 11;
        for (int d = 0; d < nd; d++, p += 8) {
            for (int q = 7; q >= 0; q--)
                shape[d] = shape[d] << 8 | b[p + q];
            cnt *= shape[d];
        }
        if (!strcmp(name, "jacobian")) m->jacobian = b[off];
        if (dtype != 10) continue; /* text and flags */
        float *f = malloc(cnt * 4);
        memcpy(f, b + off, cnt * 4); /* little-endian host */
        if (!strcmp(name, "theta_i"))
            memcpy(m->theta, f, cnt * 4), m->ntheta = (int)cnt;
        else if (!strcmp(name, "phi_i"))
            memcpy(m->phi, f, cnt * 4), m->nphi = (int)cnt;
        else if (!strcmp(name, "vndf"))
            m->vndf = f, f = NULL, m->vh = (int)shape[2], m->vw = (int)shape[3];
        else if (!strcmp(name, "rgb"))
            m->col = f, f = NULL, m->ch = (int)shape[3], m->cw = (int)shape[4];
        else if (!strcmp(name, "ndf"))
            m->ndf = f, f = NULL, m->nh = (int)shape[0], m->nw = (int)shape[1];
        else if (!strcmp(name, "sigma"))
            m->sigma = f, f = NULL;
        free(f);
    }
    free(b);
    return ok && m->vndf && m->col && m->ndf && m->sigma;
}
