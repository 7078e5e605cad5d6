/* RGL tensor_file (.bsdf) reader: synthetic files of known content written
 * here, the two real files of tests/data/measured, hostile files, and an
 * independent evaluation of the Mitsuba 3 `measured` semantics written out
 * below (its own parser, quadrature instead of the CDF tables, acos-free
 * angles) that sepbrdf must match to 1e-4 relative. */
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "measured_util.h"
#include "sepbrdf/sepbrdf.h"

#define PI 3.14159265358979323846

/* ---- a tensor_file writer ------------------------------------------------- */

typedef struct wfield {
    const char *name;
    unsigned dtype; /* 1 u8, 10 f32 */
    int ndim;
    uint64_t shape[5];
    const void *data; /* u8 or float, C order */
} wfield_t;

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

static void write_tensor(const char *path, const wfield_t *f, int nf) {
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

typedef struct mat {
    int nphi, ntheta, vw, vh, cw, ch, nw, nh, chans;
    float phi[16], theta[16];
    float *vndf, *col, *ndf, *sigma; /* [nphi][ntheta][vh][vw], [..][chans][ch][cw], [nh][nw] */
    int jacobian;
    double *norm;     /* integral of each vndf slice (set by mat_norms) */
    double cw3[3][8]; /* colour weights: RGB = sum cw3[c][k] col_k (identity for rgb) */
} mat_t;

static double rnd(unsigned long long *s) { return sb_rand01(s); }

static void mat_random(mat_t *m, unsigned long long seed, int nphi, float phi0, float phi1) {
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

static void mat_free(mat_t *m) {
    free(m->norm);
    free(m->vndf);
    free(m->col);
    free(m->ndf);
    free(m->sigma);
}

static void mat_write(const char *path, const mat_t *m, const float *wl) {
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
static double tex(const float *t, int w, int h, double x, double y) {
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
static void mat_norms(mat_t *m) {
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
static void ref_eval(const mat_t *m, const double l_in[3], const double v_in[3], double rgb[3]) {
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

/* ---- helpers ------------------------------------------------------------------ */

static sb_source_t *open_rgl(const char *path, sb_measured_info_t *info) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = NULL;
    sb_result_t r = sb_measured_open(ctx, path, NULL, &s, info);
    CHECKF(r == SB_OK, "%s: %s", path, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return s;
}

static void random_dir(unsigned long long *s, double d[3]) {
    double z = 0.02 + 0.98 * rnd(s), p = 2 * PI * rnd(s), r = sqrt(1 - z * z);
    d[0] = r * cos(p), d[1] = r * sin(p), d[2] = z;
}

/* sepbrdf and the reference at n random pairs: worst relative difference. */
static double compare(const sb_source_t *src, mat_t *m, int n, unsigned long long seed) {
    double worst = 0;
    if (!m->norm) mat_norms(m);
    for (int k = 0; k < n; k++) {
        double l[3], v[3], a[3], b[3];
        random_dir(&seed, l);
        random_dir(&seed, v);
        CHECK(sb_source_eval(src, l, v, a) == 1);
        ref_eval(m, l, v, b);
        for (int c = 0; c < 3; c++) {
            double e = fabs(a[c] - b[c]) / (fabs(b[c]) > 1e-3 ? fabs(b[c]) : 1e-3);
            if (e > worst) worst = e;
        }
    }
    return worst;
}

/* ---- cases -------------------------------------------------------------------- */

/* Constant tables: the warp is the identity, so f_r = rgb x ndf / (4 sigma)
 * / cos(theta_l) exactly. */
SB_TEST(constant_table) {
    mat_t m = {0};
    mat_random(&m, 1, 1, 0, 0);
    size_t sl = (size_t)m.ntheta;
    for (size_t i = 0; i < sl * (size_t)(m.vw * m.vh); i++)
        m.vndf[i] = 2;
    for (size_t s = 0; s < sl; s++)
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < m.cw * m.ch; i++)
                m.col[(s * 3 + (size_t)c) * (size_t)(m.cw * m.ch) + (size_t)i] = (float)(0.25 * (c + 1));
    for (int i = 0; i < m.nw * m.nh; i++)
        m.ndf[i] = 3, m.sigma[i] = 0.25f;
    const char *p = "const.bsdf";
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", sb_tmpdir("rgl"), p);
    mat_write(path, &m, NULL);
    sb_measured_info_t info;
    sb_source_t *s = open_rgl(path, &info);
    if (s) {
        CHECK(strcmp(info.format, "rgl") == 0 && info.channels == 3 && info.wavelengths == 0);
        CHECK(sb_source_flags(s) & SB_SOURCE_ISOTROPIC);
        CHECK(info.nfields >= 3 && strcmp(info.fields[0].key, "description") == 0 &&
              strcmp(info.fields[0].text, "synthetic test material") == 0);
        unsigned long long seed = 5;
        for (int k = 0; k < 200; k++) {
            double l[3], v[3], rgb[3];
            random_dir(&seed, l);
            random_dir(&seed, v);
            CHECK(sb_source_eval(s, l, v, rgb) == 1);
            for (int c = 0; c < 3; c++)
                CHECK_REL(rgb[c], 0.25 * (c + 1) * 3 / (4 * 0.25) / l[2], 1e-6);
        }
        double below[3] = {0.6, 0, -0.8}, up[3] = {0, 0, 1}, rgb[3];
        CHECK(sb_source_eval(s, below, up, rgb) == 0 && rgb[0] == 0);
        sb_source_destroy(s);
    }
    /* without the jacobian flag: the table value alone */
    m.jacobian = 0;
    mat_write(path, &m, NULL);
    if ((s = open_rgl(path, NULL))) {
        double l[3] = {0.6, 0, 0.8}, v[3] = {0, 0.28, 0.96}, rgb[3];
        sb_source_eval(s, l, v, rgb);
        CHECK_REL(rgb[1], 0.5 / 0.8, 1e-6);
        sb_source_destroy(s);
    }
    mat_free(&m);
}

/* Random tables, isotropic and anisotropic (symmetry reductions 1, 2, 4),
 * agree with the reference to 1e-4 relative. */
SB_TEST(random_vs_reference) {
    static const struct {
        int nphi;
        float p0, p1;
    } cases[] = {{1, 0, 0}, {5, (float)-PI, (float)PI}, {5, (float)-PI, 0}, {4, (float)-PI, (float)(-PI / 2)}};
    for (int k = 0; k < 4; k++) {
        mat_t m = {0};
        mat_random(&m, 11 + (unsigned long long)k, cases[k].nphi, cases[k].p0, cases[k].p1);
        char path[4200];
        snprintf(path, sizeof path, "%s/r%d.bsdf", sb_tmpdir("rgl"), k);
        mat_write(path, &m, NULL);
        sb_source_t *s = open_rgl(path, NULL);
        if (s) {
            CHECK(!!(sb_source_flags(s) & SB_SOURCE_ISOTROPIC) == (cases[k].nphi == 1));
            double e = compare(s, &m, 2000, 77 + (unsigned long long)k);
            CHECKF(e < 1e-4, "case %d (n_phi %d): worst relative difference %g", k, cases[k].nphi, e);
            sb_source_destroy(s);
        }
        mat_free(&m);
    }
}

/* A spectral table: the reference evaluates each wavelength and converts
 * after; sepbrdf converts the table first. */
SB_TEST(spectral_vs_reference) {
    mat_t m = {0};
    m.chans = 4;
    mat_random(&m, 21, 1, 0, 0);
    float wl[4] = {420, 500, 580, 660};
    double nm[4] = {420, 500, 580, 660}, w[12];
    CHECK(sb_spectral_weights(NULL, nm, 4, SB_WHITE_E, w) == SB_OK);
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 4; k++)
            m.cw3[c][k] = w[c * 4 + k];
    char path[4200];
    snprintf(path, sizeof path, "%s/spec.bsdf", sb_tmpdir("rgl"));
    mat_write(path, &m, wl);
    sb_measured_info_t info;
    sb_source_t *s = open_rgl(path, &info);
    if (s) {
        CHECK(info.wavelengths == 4 && info.wl_min == 420 && info.wl_max == 660);
        double e = compare(s, &m, 1000, 99);
        CHECKF(e < 1e-4, "worst relative difference %g", e);
        sb_source_destroy(s);
    }
    mat_free(&m);
}

/* ---- the real files ------------------------------------------------------------ */

/* The test's own reader of the fields the reference needs. */
static int load_real(const char *path, mat_t *m) {
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

SB_TEST(real_files) {
    static const char *const names[] = {"rgl_chm_orange_rgb.bsdf", "rgl_paper_white_rgb.bsdf"};
    for (int k = 0; k < 2; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", SB_MEASURED_DIR, names[k]);
        mat_t m;
        CHECKF(load_real(path, &m), "%s: missing or unreadable (shipped with the tests)", path);
        sb_measured_info_t info;
        sb_source_t *s = open_rgl(path, &info);
        if (s) {
            CHECK(info.rows == 8 * 32 * 32 && (sb_source_flags(s) & SB_SOURCE_ISOTROPIC));
            CHECK(strstr(info.fields[0].text, k ? "paper" : "CHM11E") != NULL);
            double e = compare(s, &m, 400, 3 + (unsigned long long)k);
            CHECKF(e < 1e-4, "%s: worst relative difference %g", names[k], e);
            sb_source_destroy(s);
        }
        mat_free(&m);
    }
}

/* Directional albedo at normal view, integrated over the light directions
 * (cosine-weighted: u = sin^2 theta uniform): the orange film reflects
 * mostly red, the white paper about 0.8 in every channel. */
SB_TEST(real_albedo) {
    static const char *const names[] = {"rgl_chm_orange_rgb.bsdf", "rgl_paper_white_rgb.bsdf"};
    for (int k = 0; k < 2; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", SB_MEASURED_DIR, names[k]);
        sb_source_t *s = open_rgl(path, NULL);
        if (!s) continue;
        double v[3] = {0, 0, 1}, a[3] = {0, 0, 0};
        const int nu = 2000, np = 32;
        for (int i = 0; i < nu; i++)
            for (int j = 0; j < np; j++) {
                double u = (i + 0.5) / nu, p = 2 * PI * (j + 0.5) / np, st = sqrt(u), rgb[3];
                double l[3] = {st * cos(p), st * sin(p), sqrt(1 - u)};
                sb_source_eval(s, l, v, rgb);
                for (int c = 0; c < 3; c++) /* cos dw = du dphi / 2 */
                    a[c] += PI * rgb[c] / (nu * np);
            }
        if (k == 0)
            CHECKF(a[0] > 0.5 && a[0] < 1.1 && a[1] < 0.4 && a[2] < 0.3, "orange albedo %g %g %g", a[0], a[1], a[2]);
        else
            CHECKF(a[0] > 0.5 && a[0] < 1.1 && fabs(a[0] - a[1]) < 0.1, "paper albedo %g %g %g", a[0], a[1], a[2]);
        sb_source_destroy(s);
    }
}

/* ---- hostile files ---------------------------------------------------------------- */

/* Truncations at every header byte and in the data, a bad magic, another
 * version, missing and mistyped fields, shapes that disagree, NaN values,
 * a symmetry reduction of 3, a zero projected area: each refused with the
 * file named and the code of its kind. */
SB_TEST(hostile) {
    const char *dir = sb_tmpdir("rgl");
    char good[4200], bad[4200];
    snprintf(good, sizeof good, "%s/good.bsdf", dir);
    snprintf(bad, sizeof bad, "%s/bad.bsdf", dir);
    mat_t m = {0};
    mat_random(&m, 31, 1, 0, 0);
    mat_write(good, &m, NULL);
    unsigned char *b = NULL;
    long n = file_bytes(good, &b);
    CHECK(n > 400);
    if (n <= 400) return;
    for (long cut = 0; cut < 400; cut += 7) {
        write_bytes(bad, b, (size_t)cut);
        expect_fail(bad, NULL, SB_ERR_FORMAT, NULL);
    }
    write_bytes(bad, b, (size_t)n - 100);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "past the end");
    b[13] = 1;
    write_bytes(bad, b, (size_t)n);
    expect_fail(bad, NULL, SB_ERR_UNSUPPORTED, "version");
    b[13] = 0;
    b[3] = 'X';
    write_bytes(bad, b, (size_t)n);
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_measured_opts_t o = {0};
    o.format = "rgl";
    sb_source_t *s = NULL;
    CHECK(sb_measured_open(ctx, bad, &o, &s, NULL) == SB_ERR_FORMAT && strstr(sb_context_last_error(ctx), "magic"));
    sb_context_destroy(ctx);
    free(b);

    /* NaN in the colour table; negative density; zero sigma */
    m.col[5] = NAN;
    mat_write(bad, &m, NULL);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "'rgb' value 5 is not finite");
    m.col[5] = 0.5f;
    m.vndf[3] = -1;
    mat_write(bad, &m, NULL);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "negative density");
    m.vndf[3] = 1;
    m.sigma[0] = 0;
    mat_write(bad, &m, NULL);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "sigma[0]");
    m.sigma[0] = 1;
    float t1 = m.theta[1];
    m.theta[1] = m.theta[2];
    mat_write(bad, &m, NULL);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "theta_i[2]");
    m.theta[1] = t1;
    mat_free(&m);

    /* phi_i over a third of a turn: reduction 3 */
    mat_t a = {0};
    mat_random(&a, 32, 4, (float)-PI, (float)(-PI / 3));
    mat_write(bad, &a, NULL);
    expect_fail(bad, NULL, SB_ERR_UNSUPPORTED, "symmetry reduction 3");
    mat_free(&a);

    /* fields missing, mistyped, or of other shapes */
    float th[2] = {0, 1}, ph[1] = {0}, t22[8] = {1, 1, 1, 1, 1, 1, 1, 1}, v[4 * 4];
    float c[2 * 3 * 4];
    for (int k = 0; k < 24; k++)
        c[k] = 1;
    for (int k = 0; k < 16; k++) /* room for the 3-slice vndf below */
        v[k] = 1;
    unsigned char jac = 1;
    wfield_t f[7] = {
        {"theta_i", 10, 1, {2}, th},   {"phi_i", 10, 1, {1}, ph},        {"ndf", 10, 2, {2, 2}, t22},
        {"sigma", 10, 2, {2, 2}, t22}, {"vndf", 10, 4, {1, 2, 2, 2}, v}, {"rgb", 10, 5, {1, 2, 3, 2, 2}, c},
        {"jacobian", 1, 1, {1}, &jac},
    };
    write_tensor(good, f, 7);
    if ((s = open_rgl(good, NULL))) sb_source_destroy(s);
    write_tensor(bad, f, 6);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "jacobian");
    f[4].name = "vndx";
    write_tensor(bad, f, 7);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "missing field 'vndf'");
    f[4].name = "vndf";
    f[4].shape[1] = 3;
    write_tensor(bad, f, 7);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "slices");
    f[4].shape[1] = 2;
    f[5].dtype = 1;
    write_tensor(bad, f, 7);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "float32");
}

/* ---- the command line ----------------------------------------------------------- */

static char out[1 << 16];

static int cli(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int cli(const char *fmt, ...) {
    char args[8192], cmd[9000];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    snprintf(cmd, sizeof cmd, "%s %s 2>&1", SB_CLI, args);
    return sb_run(cmd, out, sizeof out);
}

/* info, factor and render take an RGL file like any source; a broken one
 * is an input error (exit 2). */
SB_TEST(cli_rgl) {
    const char *dir = sb_tmpdir("rglcli");
    int rc = cli("info %s/rgl_chm_orange_rgb.bsdf --res 8", SB_MEASURED_DIR);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    CHECK(strstr(out, "format        rgl") && strstr(out, "description   TeckWrap vinyl wrapping film"));
    CHECK(strstr(out, "layout        isotropic, 8 theta_i slices"));
    rc = cli("info %s/rgl_paper_white_rgb.bsdf --res 8 --json", SB_MEASURED_DIR);
    CHECKF(rc == 0 && strstr(out, "\"description\": \"White A4 paper (160 gsm)\""), "rc %d: %s", rc, out);
    rc = cli("factor %s/rgl_paper_white_rgb.bsdf --param iso --res 16 --terms 2 -q -o %s/f", SB_MEASURED_DIR, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char p[4300];
    snprintf(p, sizeof p, "%s/f/report.json", dir);
    CHECK(sb_file_exists(p));
    rc = cli("render %s/rgl_paper_white_rgb.bsdf --param iso --res 8 -J 1 --size 24 -q -o %s/r", SB_MEASURED_DIR, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(p, sizeof p, "%s/broken.bsdf", dir);
    write_bytes(p, (const unsigned char *)"tensor_file\0\1\0\5\0\0\0", 18);
    CHECK(cli("info %s", p) == 2 && strstr(out, "broken.bsdf"));
    CHECK(cli("factor %s --res 8 --terms 1 -q -o %s/g", p, dir) == 2);
}
