/* RGL tensor_file (.bsdf) reader: synthetic files of known content written
 * here, the two real files of tests/data/measured, hostile files, and an
 * independent evaluation of the Mitsuba 3 `measured` semantics (rgl_ref.c:
 * its own parser, quadrature instead of the CDF tables, acos-free angles)
 * that sepbrdf must match to 1e-4 relative. */
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "measured_util.h"
#include "rgl_ref.h"
#include "sepbrdf/sepbrdf.h"

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
        ref_eval(m, l, v, b, NULL, NULL);
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

/* The vh layout follows how an RGL file stores a material (the view picks
 * the slices, each a table over the half vector): on the white paper,
 * factored as f cos theta_i at R = 16, J = 4, its reconstruction, measured
 * at random pairs against the independent reference evaluator (rgl_ref.c,
 * not the library's reader), agrees with the headline it reports within
 * 15 %, and is below 0.6 of hd's (Kautz-McCool) error on the same grid
 * (measured on the white paper: about 0.03 against 0.07). */
#define VH_PAIRS 12000

/* The relative L2 error of f cos theta_i of `param`'s fit at the pairs
 * (l, v) whose reference values are ref. */
static double rgl_fit_error(const char *path, const char *param, const double (*l)[3], const double (*v)[3],
                            const double (*ref)[3], double *headline) {
    sb_job_opts_t o = {0};
    o.source = path;
    o.param = param;
    o.form = "cos";
    o.weighted = 1;
    o.res = 16;
    o.terms = 4;
    o.fit_max_iters = 20; /* the masked fits stopped early, as auto screens */
    o.fit_tol = 1e-3;
    o.warp = "merl";
    sb_job_t *job = NULL;
    sb_result_t r = sb_job_run(NULL, &o, &job);
    CHECKF(r == SB_OK, "%s %s: %s", path, param, sb_result_name(r));
    if (r != SB_OK) return INFINITY;
    *headline = sb_job_headline(job, 4);
    double e2 = 0, t2 = 0, b[3];
    for (int n = 0; n < VH_PAIRS; n++) {
        if (!sb_factors_eval(sb_job_factors(job), sb_job_param(job), SB_FORM_COS, 4, l[n], v[n], b)) continue;
        for (int c = 0; c < 3; c++) {
            e2 += (ref[n][c] - b[c]) * (ref[n][c] - b[c]) * l[n][2] * l[n][2];
            t2 += ref[n][c] * ref[n][c] * l[n][2] * l[n][2];
        }
    }
    sb_job_destroy(job);
    return sqrt(e2 / t2);
}

SB_TEST(vh_layout_out_of_sample) {
    /* uniform pairs: the paper's broad lobe (the orange film's mirror peak
     * would need far more pairs than a test affords) */
    static const char *const names[] = {"rgl_paper_white_rgb.bsdf"};
    static double l[VH_PAIRS][3], v[VH_PAIRS][3], ref[VH_PAIRS][3];
    for (int k = 0; k < 1; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", SB_MEASURED_DIR, names[k]);
        mat_t m;
        CHECKF(load_real(path, &m), "%s: missing or unreadable", path);
        mat_norms(&m);
        unsigned long long st = 5;
        for (int n = 0; n < VH_PAIRS; n++) {
            for (int q = 0; q < 2; q++) { /* uniform over the hemisphere */
                double *w = q ? v[n] : l[n], z = rnd(&st), ph = 2 * SB_PI * rnd(&st), sn = sqrt(fmax(1 - z * z, 0));
                w[0] = sn * cos(ph), w[1] = sn * sin(ph), w[2] = z;
            }
            ref_eval(&m, l[n], v[n], ref[n], NULL, NULL);
        }
        double hv = NAN, hh = NAN;
        double ev = rgl_fit_error(path, "vh", l, v, ref, &hv), eh = rgl_fit_error(path, "hd", l, v, ref, &hh);
        CHECKF(ev < 0.6 * eh, "%s: vh %g, hd %g", names[k], ev, eh);
        CHECKF(fabs(ev - hv) < 0.15 * ev, "%s: vh reports %g, the reference measures %g", names[k], hv, ev);
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

/* ---- the measured samples ----------------------------------------------------- */

/* One expected sample: a colour node of a slice at its directions. */
typedef struct node {
    double l[3], v[3], f[3];
    int used;
} node_t;

/* The nodes of m when its VNDF is uniform: the warp is then the identity,
 * u_m = s = (x/(cw-1), y/(ch-1)), so each node's directions follow in
 * closed form: the view at the slice's angles, m from u_m (theta_m =
 * u_x^2 pi/2, phi_m = 2 pi u_y - pi, plus the view's azimuth when
 * isotropic; a reduced table's view in the part it measures, y <= 0), the
 * light l = v reflected about m; f_r = max(0, colour x ndf(u_m) /
 * (4 sigma(u_v))) / l_z.  Nodes with l at or below the horizon
 * are left out.  Returns the count (at most max). */
static size_t uniform_nodes(const mat_t *m, node_t *out, size_t max) {
    size_t n = 0, nodes = (size_t)(m->cw * m->ch);
    int red = m->nphi > 2 ? (int)lround(2 * PI / (m->phi[m->nphi - 1] - m->phi[0])) : 1;
    for (int p = 0; p < m->nphi; p++)
        for (int t = 0; t < m->ntheta; t++)
            for (int y = 0; y < m->ch; y++)
                for (int x = 0; x < m->cw; x++) {
                    double tv = m->theta[t], pv = m->phi[p];
                    double v[3] = {sin(tv) * cos(pv), sin(tv) * sin(pv), cos(tv)};
                    if (red >= 2) v[1] = -fabs(v[1]); /* in the measured part, as the evaluation mirrors */
                    if (red == 4) v[0] = -fabs(v[0]);
                    double az = atan2(v[1], v[0]);
                    double um[2] = {(double)x / (m->cw - 1), (double)y / (m->ch - 1)};
                    double uv[2] = {sqrt(tv / (PI / 2)), (az + PI) / (2 * PI)};
                    double tm = um[0] * um[0] * PI / 2, pm = 2 * PI * um[1] - PI + (m->nphi <= 2 ? az : 0);
                    double h[3] = {sin(tm) * cos(pm), sin(tm) * sin(pm), cos(tm)};
                    double vh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2];
                    node_t e = {{2 * vh * h[0] - v[0], 2 * vh * h[1] - v[1], 2 * vh * h[2] - v[2]}, {0}, {0}, 0};
                    if (!(e.l[2] > 1e-9 && v[2] > 1e-9) || n == max) continue;
                    double jac = m->jacobian ? tex(m->ndf, m->nw, m->nh, um[0], um[1]) /
                                                   (4 * tex(m->sigma, m->nw, m->nh, uv[0], uv[1]))
                                             : 1;
                    size_t q = (size_t)(p * m->ntheta + t);
                    for (int c = 0; c < 3; c++) {
                        double val = m->col[(q * 3 + (size_t)c) * nodes + (size_t)(y * m->cw + x)] * jac;
                        e.v[c] = v[c];
                        e.f[c] = val > 0 ? val / e.l[2] : 0;
                    }
                    out[n++] = e;
                }
    return n;
}

static int near3(const double a[3], const double b[3], double tol) {
    return fabs(a[0] - b[0]) <= tol && fabs(a[1] - b[1]) <= tol && fabs(a[2] - b[2]) <= tol;
}

static void make_uniform(mat_t *m) {
    for (size_t i = 0; i < (size_t)(m->nphi * m->ntheta * m->vw * m->vh); i++)
        m->vndf[i] = 2;
}

/* The layouts whose samples are checked: isotropic, and anisotropic with
 * symmetry reduction 2. */
static const struct {
    int nphi;
    float p0, p1;
} sample_cases[] = {{1, 0, 0}, {5, (float)-PI, 0}};

/* With a uniform VNDF the samples are exactly the nodes in closed form
 * (uniform_nodes), one for one: isotropic, and anisotropic with symmetry
 * reduction 2. */
SB_TEST(samples_uniform_warp) {
    for (int k = 0; k < 2; k++) {
        mat_t m = {0};
        mat_random(&m, 41 + (unsigned long long)k, sample_cases[k].nphi, sample_cases[k].p0, sample_cases[k].p1);
        make_uniform(&m);
        char path[4200];
        snprintf(path, sizeof path, "%s/u%d.bsdf", sb_tmpdir("rgl"), k);
        mat_write(path, &m, NULL);
        size_t max = (size_t)(m.nphi * m.ntheta * m.cw * m.ch), n;
        node_t *want = calloc(max, sizeof *want);
        n = uniform_nodes(&m, want, max);
        sb_source_t *s = open_rgl(path, NULL);
        if (s) {
            size_t got = 0, unmatched = 0;
            CHECK(sb_source_sample_count(s) == max);
            for (size_t i = 0; i < sb_source_sample_count(s); i++) {
                double wi[3], wo[3], f[3];
                if (!sb_source_sample(s, i, wi, wo, f)) continue;
                got++;
                size_t j = 0;
                for (; j < n; j++) /* x = 0: all rows share one pair, told apart by the value */
                    if (!want[j].used && near3(want[j].l, wi, 1e-9) && near3(want[j].v, wo, 1e-9) &&
                        fabs(want[j].f[0] - f[0]) <= 1e-9 * (1 + fabs(f[0])) &&
                        fabs(want[j].f[2] - f[2]) <= 1e-9 * (1 + fabs(f[2])))
                        break;
                if (j < n)
                    want[j].used = 1;
                else
                    unmatched++;
            }
            CHECKF(got == n && unmatched == 0, "case %d: %zu samples, %zu nodes above the horizon, %zu unmatched", k,
                   got, n, unmatched);
            sb_source_destroy(s);
        }
        free(want);
        mat_free(&m);
    }
}

/* With a random VNDF each sample lands, by the reference's own inversion
 * (quadrature), on a colour node of its view's slice and holds that node's
 * value; no node twice.  At x = 0 (theta_m = 0) all rows of a slice meet
 * at one pair, the seam rows y = 0 and y = ch - 1 are one azimuth, and an
 * anisotropic table's slices at theta_i = 0 one view (each read as the
 * reference reads the one of its azimuth: skipped). */
SB_TEST(samples_random_warp) {
    for (int k = 0; k < 2; k++) {
        mat_t m = {0};
        mat_random(&m, 51 + (unsigned long long)k, sample_cases[k].nphi, sample_cases[k].p0, sample_cases[k].p1);
        for (int q = 0; q < m.nphi * m.ntheta; q++) /* periodic in phi_m, as measured data are */
            for (int x = 0; x < m.vw; x++)
                m.vndf[((size_t)q * (size_t)m.vh + (size_t)m.vh - 1) * (size_t)m.vw + (size_t)x] =
                    m.vndf[(size_t)q * (size_t)(m.vh * m.vw) + (size_t)x];
        for (int i = 0; i < m.nw; i++)
            m.ndf[m.nw + i] = m.ndf[i];
        mat_norms(&m);
        char path[4200];
        snprintf(path, sizeof path, "%s/w%d.bsdf", sb_tmpdir("rgl"), k);
        mat_write(path, &m, NULL);
        size_t nodes = (size_t)(m.cw * m.ch), slices = (size_t)(m.nphi * m.ntheta), bad = 0, twice = 0, got = 0;
        unsigned char *hit = calloc(slices * nodes, 1);
        sb_source_t *s = open_rgl(path, NULL);
        for (size_t i = 0; s && i < sb_source_sample_count(s); i++) {
            double l[3], v[3], f[3], ref[3], st[2], jac;
            if (!sb_source_sample(s, i, l, v, f)) continue;
            got++;
            ref_eval(&m, l, v, ref, st, &jac);
            double X = st[0] * (m.cw - 1), Y = st[1] * (m.ch - 1), tv = atan2(hypot(v[0], v[1]), v[2]);
            int x = (int)lround(X), y = (int)lround(Y), t = 0, p = 0;
            while (t + 1 < m.ntheta && fabs(m.theta[t] - tv) > 1e-6)
                t++;
            while (p + 1 < m.nphi && fabs(m.phi[p] - atan2(v[1], v[0])) > 1e-6)
                p++;
            if (m.nphi > 1 && t == 0) continue; /* a view along the normal: each phi_i slice its own */
            size_t q = (size_t)(p * m.ntheta + t);
            int on_node = fabs(X - x) < 1e-6 && (x == 0 || fabs(Y - y) < 1e-6) && fabs(m.theta[t] - tv) < 1e-6;
            /* the node's value: the row y or its seam twin (x = 0: the pole,
             * where each row's ndf factor is its own) */
            int value_ok = x == 0;
            for (int r = 0; r < m.ch && on_node && !value_ok; r++) {
                if (r != y && !((y == 0 || y == m.ch - 1) && (r == 0 || r == m.ch - 1))) continue;
                double val = m.col[(q * 3) * nodes + (size_t)(r * m.cw + x)] * jac, want = val > 0 ? val / l[2] : 0;
                if (fabs(f[0] - want) <= 1e-6 * (1 + fabs(want))) {
                    value_ok = 1;
                    y = r;
                }
            }
            if (!on_node || !value_ok) {
                if (bad++ < 5) sb_test_fail(__FILE__, __LINE__, "case %d sample %zu: X %g Y %g f %g", k, i, X, Y, f[0]);
                continue;
            }
            if (x != 0 && hit[q * nodes + (size_t)(y * m.cw + x)]++) twice++;
            if (x != 0 && y != 0 && y != m.ch - 1) /* inside: the reference reads the same value */
                CHECK(fabs(ref[1] - f[1]) <= 1e-5 * (1 + fabs(f[1])));
        }
        CHECKF(bad == 0 && twice == 0 && got > slices * nodes / 2, "case %d: %zu samples, %zu off a node, %zu twice", k,
               got, bad, twice);
        sb_source_destroy(s);
        free(hit);
        mat_free(&m);
    }
}

/* The errors of a factorisation at an RGL table's samples equal the same
 * formula evaluated here on the closed-form nodes of a uniform-VNDF table
 * with the public per-pair reconstruction (sb_factors_eval); the table's
 * own evaluation reads its samples back (source_rel_l2 = 0). */
SB_TEST(sample_errors_independent) {
    mat_t m = {0};
    mat_random(&m, 61, 1, 0, 0);
    make_uniform(&m);
    for (int t = 0; t < m.ntheta; t++) /* no view along the normal: the io textures' azimuth is arbitrary there */
        m.theta[t] = (float)(0.05 + 0.9 * m.theta[t]);
    /* consistent where nodes meet: one value at theta_m = 0 (x = 0), the
     * seam rows alike and an NDF periodic in phi, so the table's own
     * evaluation reads each sample back */
    for (int i = 0; i < m.nw; i++)
        m.ndf[m.nw + i] = m.ndf[i];
    for (int q = 0; q < m.ntheta * 3; q++) {
        float *c = m.col + (size_t)q * (size_t)(m.cw * m.ch);
        for (int y = 0; y < m.ch; y++)
            c[y * m.cw] = c[0];
        for (int x = 0; x < m.cw; x++)
            c[(m.ch - 1) * m.cw + x] = c[x];
    }
    char path[4200];
    snprintf(path, sizeof path, "%s/e.bsdf", sb_tmpdir("rgl"));
    mat_write(path, &m, NULL);
    size_t max = (size_t)(m.ntheta * m.cw * m.ch);
    node_t *want = calloc(max, sizeof *want);
    size_t n = uniform_nodes(&m, want, max);
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = open_rgl(path, NULL);
    sb_job_opts_t o = {0};
    o.param = "io";
    o.res = 12;
    o.terms = 4;
    sb_job_t *job = NULL;
    CHECKF(s && sb_job_run_source(ctx, s, &o, &job) == SB_OK, "%s", sb_context_last_error(ctx));
    sb_sample_errors_t se;
    if (job) {
        const sb_factors_t *f = sb_job_factors(job);
        const sb_param_t *p = sb_job_param(job);
        CHECK(sb_measured_sample_errors(ctx, s, f, p, sb_job_form(job), &se) == SB_OK);
        CHECKF(se.samples == n && se.terms == 4 && se.source_rel_l2 < 1e-9, "%zu samples of %zu nodes, source %g",
               se.samples, n, se.source_rel_l2);
        for (size_t J = 1; J <= 4; J++) {
            double num = 0, den = 0;
            for (size_t j = 0; j < n; j++) {
                double rec[3], w2 = pow(want[j].l[2] * want[j].v[2], 2);
                if (!sb_factors_eval(f, p, sb_job_form(job), J, want[j].l, want[j].v, rec))
                    rec[0] = rec[1] = rec[2] = 0;
                for (int c = 0; c < 3; c++) {
                    num += (rec[c] - want[j].f[c]) * (rec[c] - want[j].f[c]) * w2;
                    den += want[j].f[c] * want[j].f[c] * w2;
                }
            }
            CHECK_REL(se.rel_l2[J - 1], sqrt(num / den), 1e-6);
        }
    }
    sb_job_destroy(job);
    sb_source_destroy(s);
    sb_context_destroy(ctx);
    free(want);
    mat_free(&m);
}

/* More terms than the file has theta_i slices (hsw3 D1): auto fits vndf
 * with all its rows (the file's nodes, returned exactly) and says so,
 * where it left vndf out ("4 terms exceed the 3 rows/columns of vndf")
 * and kept another layout at J (the orange film at J = 12: vh, headline
 * 0.096; vndf 1.7e-7 at its 8 slices).  The real film cut to its first
 * three slices, the default J = 4. */
SB_TEST(terms_beyond_the_slices) {
    mat_t m = {0};
    CHECK(load_real(SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf", &m));
    m.ntheta = 3; /* phi_i x theta_i x ...: the first slices are the first values */
    char dir[4096], cmd[9000], out[16384];
    snprintf(dir, sizeof dir, "%s", sb_tmpdir("rgl"));
    snprintf(cmd, sizeof cmd, "%s/slices.bsdf", dir);
    mat_write(cmd, &m, NULL);
    snprintf(cmd, sizeof cmd, "%s factor %s/slices.bsdf -o %s/out 2>&1", SB_CLI, dir, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECKF(strstr(out, "warning: 3 terms fitted, not the 4 asked: layout vndf") != NULL, "%s", out);
    CHECKF(strstr(out, "vndf, 3 x 1024 matrix") != NULL, "%s", out);
    /* J = 3: the file's nodes returned (the report's headline line) */
    const char *row = strstr(out, "\n   3 ");
    CHECKF(row && strtod(row + 5, NULL) < 1e-4, "%s", out);
    /* a budget's search takes the J given as fixed: vndf holds no entry there, the others are searched */
    snprintf(cmd, sizeof cmd, "%s factor %s/slices.bsdf -J 6 --budget 98304 -o %s/budget 2>&1", SB_CLI, dir, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    /* render's J beyond the terms fitted: the last (it failed, "6 terms asked, the factors have 3") */
    snprintf(cmd, sizeof cmd, "%s render %s/slices.bsdf -J 2,6 -s 16 -o %s/render 2>&1", SB_CLI, dir, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    mat_free(&m);
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
    expect_fail(bad, NULL, SB_ERR_FORMAT, "'rgb' holds NaN at index 5 (of ");
    m.col[5] = 0.5f;
    /* every colour value negated (a sign error): read as black before */
    size_t ncol = (size_t)(m.nphi * m.ntheta * m.chans * m.ch * m.cw);
    for (size_t k = 0; k < ncol; k++)
        m.col[k] = -m.col[k];
    mat_write(bad, &m, NULL);
    expect_fail(bad, NULL, SB_ERR_FORMAT, "a BRDF is not negative");
    for (size_t k = 0; k < ncol; k++)
        m.col[k] = -m.col[k];
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
    expect_fail(bad, NULL, SB_ERR_FORMAT,
                "uint8 (dtype 1), need"); /* the dtype by its name (hsw3), not "dtype 1" alone */
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
    /* errors at the table's own samples: 7 slices below 90 deg x 32 x 32 nodes */
    char cmd[4500];
    snprintf(cmd, sizeof cmd, "grep -q '\"samples\": 7168,' '%s'", p);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    rc = cli("render %s/rgl_paper_white_rgb.bsdf --param iso --res 8 -J 1 --size 24 -q -o %s/r", SB_MEASURED_DIR, dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(p, sizeof p, "%s/broken.bsdf", dir);
    write_bytes(p, (const unsigned char *)"tensor_file\0\1\0\5\0\0\0", 18);
    CHECK(cli("info %s", p) == 2 && strstr(out, "broken.bsdf"));
    CHECK(cli("factor %s --res 8 --terms 1 -q -o %s/g", p, dir) == 2);
}
