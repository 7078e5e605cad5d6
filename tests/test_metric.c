/* The comparable metric: its fast paths (isotropic source table, tabulated
 * sides of io / io-area, rotation classes of iso) against a straightforward
 * evaluation of every pair of the reference grid written out here. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define MAXJ 8

/* ---- sources ------------------------------------------------------------ */

/* A model wrapped with chosen flags (none: no isotropic fast path) and,
 * for `holes`, missing pairs and non-finite values that depend on the
 * elevations only (so the wrapped source stays isotropic). */
typedef struct wrap {
    sb_source_t *inner;
    int holes;
} wrap_t;

static int wrap_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const wrap_t *w = self;
    int known = sb_source_eval(w->inner, wi, wo, rgb);
    if (w->holes && wi[2] * wo[2] < 0.1) {
        rgb[0] = rgb[1] = rgb[2] = 0;
        return 0;
    }
    if (w->holes && wi[2] > 0.97 && wo[2] > 0.9) rgb[1] = NAN;
    return known;
}

static void wrap_destroy(void *self) {
    wrap_t *w = self;
    sb_source_destroy(w->inner);
    free(w);
}

static sb_source_t *source(const char *spec, unsigned flags, int holes) {
    sb_source_t *inner = NULL, *s = NULL;
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_result_t r = sb_model_create(ctx, spec, &inner);
    CHECKF(r == SB_OK, "model %s: %s", spec, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    wrap_t *w = malloc(sizeof *w);
    w->inner = inner;
    w->holes = holes;
    sb_source_ops_t ops = {wrap_eval, wrap_destroy};
    CHECK(sb_source_create(NULL, &ops, w, flags, "wrapped", &s) == SB_OK);
    return s;
}

#define GOLD "microfacet:base=gold,roughness=0.4"

/* ---- factors -------------------------------------------------------------- */

static sb_param_t *param_as(sb_param_kind_t kind, size_t res, double theta_max_deg, int plain) {
    sb_param_opts_t o = {0};
    o.res = res;
    o.plain = plain;
    o.theta_max = theta_max_deg * SB_PI / 180;
    sb_param_t *p = NULL;
    CHECK(sb_param_create(NULL, kind, &o, &p) == SB_OK);
    return p;
}
static sb_param_t *param(sb_param_kind_t kind, size_t res, double theta_max_deg) {
    return param_as(kind, res, theta_max_deg, 0);
}

/* J plain SVD terms of the sampled matrix (zero-filled where unknown),
 * the terms after the first tripled so that every parameterisation has
 * negative lobes to count. */
static sb_factors_t *factors(const sb_source_t *s, const sb_param_t *p, sb_form_t form, size_t J) {
    sb_matrix_t m;
    sb_matrix_opts_t mo = {0};
    mo.form = form;
    CHECK(sb_matrix_build(NULL, s, p, &mo, &m) == SB_OK);
    sb_plan_opts_t po = {0};
    po.terms = J;
    po.zero_fill = 1;
    sb_plan_t *plan = NULL;
    sb_factors_t *f = NULL;
    CHECK(sb_plan_create(NULL, m.rows, m.cols, &po, &plan) == SB_OK);
    CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
    sb_plan_destroy(plan);
    sb_matrix_free(&m);
    size_t w, h;
    sb_factors_size(f, SB_SIDE_G, &w, &h);
    for (size_t j = 1; j < J; j++)
        for (size_t c = 0; c < 3; c++)
            for (size_t i = 0; i < w * h; i++)
                sb_factors_tex(f, SB_SIDE_G, j, c)[i] *= 3;
    return f;
}

/* ---- the reference ---------------------------------------------------------- */

typedef struct ref {
    double rel[MAXJ];
    size_t neg[MAXJ], known;
} ref_t;

/* Every pair of the R x R reference io grid (cell centres on [0, pi/2] x
 * [0, 2pi)): source and sb_factors_eval, weight dw_i dw_o (c_i c_o)^2 with
 * dw = dphi (cos th_lo - cos th_hi). */
static void reference(const sb_source_t *s, const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t R,
                      ref_t *out) {
    size_t J = sb_factors_terms(f), N = R * R;
    double dt = SB_PI / 2 / (double)R, dp = 2 * SB_PI / (double)R, num[MAXJ] = {0}, den = 0;
    memset(out, 0, sizeof *out);
    for (size_t k = 0; k < N; k++) {
        size_t it = k % R, ip = k / R;
        double wi[3], dwi = dp * (cos(it * dt) - cos((it + 1) * dt));
        sb_dir_from_angles((it + 0.5) * dt, (ip + 0.5) * dp, wi);
        for (size_t l = 0; l < N; l++) {
            size_t ot = l % R, op = l / R;
            double wo[3], dwo = dp * (cos(ot * dt) - cos((ot + 1) * dt)), fv[3], rec[3];
            sb_dir_from_angles((ot + 0.5) * dt, (op + 0.5) * dp, wo);
            if (!sb_source_eval(s, wi, wo, fv) || !isfinite(fv[0] + fv[1] + fv[2])) continue;
            out->known++;
            double cc = wi[2] * wo[2], w = dwi * dwo * cc * cc;
            den += w * (fv[0] * fv[0] + fv[1] * fv[1] + fv[2] * fv[2]);
            for (size_t j = 0; j < J; j++) {
                sb_factors_eval(f, p, form, j + 1, wi, wo, rec);
                double e2 = 0;
                for (int c = 0; c < 3; c++)
                    e2 += (rec[c] - fv[c]) * (rec[c] - fv[c]);
                num[j] += w * e2;
                out->neg[j] += rec[0] < 0 || rec[1] < 0 || rec[2] < 0;
            }
        }
    }
    for (size_t j = 0; j < J; j++)
        out->rel[j] = sqrt(num[j] / den);
}

/* sb_metric_compute agrees with the reference: rel_l2 to 1e-10, counts
 * exactly.  Returns the reference's negative pairs summed over J'. */
static size_t check(const sb_source_t *s, const sb_factors_t *f, const sb_param_t *p, sb_form_t form, size_t R,
                    const char *what) {
    sb_metric_opts_t mo = {0};
    mo.res = R;
    sb_metric_t m;
    ref_t r;
    CHECK(sb_metric_compute(NULL, s, f, p, form, &mo, &m) == SB_OK);
    reference(s, f, p, form, R, &r);
    size_t J = sb_factors_terms(f);
    CHECK(m.terms == J && m.pairs == R * R * R * R);
    CHECKF(m.known == r.known, "%s: known %zu, reference %zu", what, m.known, r.known);
    size_t negs = 0;
    for (size_t j = 0; j < J; j++) {
        CHECKF(fabs(m.rel_l2[j] - r.rel[j]) <= 1e-10 * r.rel[j], "%s J'=%zu: rel_l2 %.17g, reference %.17g", what,
               j + 1, m.rel_l2[j], r.rel[j]);
        long n = lround(m.neg_frac[j] * (double)m.known);
        CHECKF(n == (long)r.neg[j], "%s J'=%zu: %ld negative pairs, reference %zu", what, j + 1, n, r.neg[j]);
        negs += r.neg[j];
    }
    return negs;
}

static const sb_param_kind_t kinds[] = {SB_PARAM_IO, SB_PARAM_IO_AREA, SB_PARAM_HD, SB_PARAM_ISO, SB_PARAM_VH};

/* Every parameterisation, an isotropic source (table; sides or rotation
 * classes) and the same source without the flag, forms f, cos and cos2.
 * R = 10 is even, so the iso classes with wo the mirror of wi occur.  The
 * plain sum (plain=1) has negative lobes to count; by default the
 * reconstruction is max(0, sum), as the snippet's, and has none. */
SB_TEST(matches_reference) {
    sb_source_t *src[2] = {source(GOLD, SB_SOURCE_ISOTROPIC, 0), source(GOLD, 0, 0)};
    const sb_form_t forms[] = {SB_FORM_F, SB_FORM_COS, SB_FORM_COS2};
    for (size_t k = 0; k < 4; k++) {
        sb_param_t *p = param_as(kinds[k], 6, 0, 1), *clamped = param(kinds[k], 6, 0);
        sb_factors_t *fc = factors(src[0], clamped, SB_FORM_F, 4);
        CHECKF(check(src[0], fc, clamped, SB_FORM_F, 10, sb_param_spec(clamped)) == 0, "%s: negative pairs",
               sb_param_spec(clamped));
        sb_factors_destroy(fc);
        sb_param_destroy(clamped);
        size_t negs = 0;
        for (int i = 0; i < 2; i++)
            for (size_t fm = 0; fm < 3; fm++) {
                if (i == 1 && forms[fm] == SB_FORM_COS) continue; /* the plain path does not depend on the form */
                sb_factors_t *f = factors(src[0], p, forms[fm], 4);
                char what[96];
                snprintf(what, sizeof what, "%s, %s, form %s", sb_param_spec(p), i ? "plain" : "isotropic",
                         sb_form_name(forms[fm]));
                negs += check(src[i], f, p, forms[fm], 10, what);
                sb_factors_destroy(f);
            }
        CHECKF(negs > 0, "%s: no negative pair to count", sb_param_spec(p));
        sb_param_destroy(p);
    }
    sb_source_destroy(src[0]);
    sb_source_destroy(src[1]);
}

/* check() on every parameterisation (res 6, theta_max in degrees, 0: 90)
 * for J terms fitted to `fit` in form cos2, source s, reference grid R,
 * with the memory limit `limit` (0: the default) around the metric. */
static void every_kind(const sb_source_t *fit, const sb_source_t *s, double theta_max_deg, size_t J, size_t R,
                       size_t limit, const char *what) {
    for (size_t k = 0; k < 4; k++) {
        sb_param_t *p = param(kinds[k], 6, theta_max_deg);
        sb_factors_t *f = factors(fit, p, SB_FORM_COS2, J);
        char label[128];
        snprintf(label, sizeof label, "%s, %s", sb_param_spec(p), what);
        sb_set_memory_limit(limit);
        check(s, f, p, SB_FORM_COS2, R, label);
        sb_set_memory_limit(0);
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
}

/* Missing pairs and non-finite values are skipped in every path; an odd R. */
SB_TEST(holes_and_nan) {
    sb_source_t *iso = source(GOLD, SB_SOURCE_ISOTROPIC, 1), *plain = source(GOLD, 0, 1);
    every_kind(iso, iso, 0, 3, 9, 0, "isotropic, holes");
    every_kind(iso, plain, 0, 3, 9, 0, "plain, holes");
    sb_source_destroy(iso);
    sb_source_destroy(plain);
}

/* A reference ring centred on the cap's rim: theta_max = 9 degrees and
 * R = 15 put ring 1 at 9 degrees, where the cap test of 3 of its 15
 * directions fails by rounding. */
SB_TEST(ring_on_theta_max) {
    sb_source_t *s = source(GOLD, SB_SOURCE_ISOTROPIC, 0);
    every_kind(s, s, 9, 3, 15, 0, "ring on the rim");
    sb_source_destroy(s);
}

/* One-channel factors (the same texture for R, G and B). */
SB_TEST(one_channel) {
    sb_source_t *s = source(GOLD, SB_SOURCE_ISOTROPIC, 0);
    for (size_t k = 0; k < 4; k++) {
        sb_param_t *p = param(kinds[k], 6, 0);
        sb_factors_t *f3 = factors(s, p, SB_FORM_F, 3), *f1 = NULL;
        size_t gw, gh, hw, hh;
        sb_factors_size(f3, SB_SIDE_G, &gw, &gh);
        sb_factors_size(f3, SB_SIDE_H, &hw, &hh);
        CHECK(sb_factors_create(NULL, 3, 1, gw, gh, hw, hh, &f1) == SB_OK);
        for (size_t j = 0; j < 3; j++) {
            memcpy(sb_factors_tex(f1, SB_SIDE_G, j, 0), sb_factors_tex_const(f3, SB_SIDE_G, j, 1),
                   gw * gh * sizeof(double));
            memcpy(sb_factors_tex(f1, SB_SIDE_H, j, 0), sb_factors_tex_const(f3, SB_SIDE_H, j, 1),
                   hw * hh * sizeof(double));
        }
        check(s, f1, p, SB_FORM_F, 8, sb_param_spec(p));
        sb_factors_destroy(f1);
        sb_factors_destroy(f3);
        sb_param_destroy(p);
    }
    sb_source_destroy(s);
}

/* Fixed units summed in a fixed order: the same bits on any thread count. */
SB_TEST(thread_count_independent) {
    sb_source_t *src[2] = {source(GOLD, SB_SOURCE_ISOTROPIC, 0), source(GOLD, 0, 0)};
    for (size_t k = 0; k < 4; k++) {
        sb_param_t *p = param(kinds[k], 8, 0);
        sb_factors_t *f = factors(src[0], p, SB_FORM_COS2, 4);
        for (int i = 0; i < 2; i++) {
            sb_metric_t a, b;
            sb_metric_opts_t mo = {0};
            mo.res = 12;
            mo.threads = 1;
            CHECK(sb_metric_compute(NULL, src[i], f, p, SB_FORM_COS2, &mo, &a) == SB_OK);
            const int threads[] = {2, 3, 7, 12, 64};
            for (size_t t = 0; t < sizeof threads / sizeof *threads; t++) {
                mo.threads = threads[t];
                CHECK(sb_metric_compute(NULL, src[i], f, p, SB_FORM_COS2, &mo, &b) == SB_OK);
                CHECKF(memcmp(&a, &b, sizeof a) == 0, "%s, source %d: %d threads differ from 1", sb_param_spec(p), i,
                       threads[t]);
            }
        }
        sb_factors_destroy(f);
        sb_param_destroy(p);
    }
    sb_source_destroy(src[0]);
    sb_source_destroy(src[1]);
}

/* Under a memory limit that refuses the speed-ups' tables (R = 10:
 * directions 2400 bytes, sums 800; source table 24 000, sides 9600 each)
 * the per-pair path gives the same metric. */
SB_TEST(without_tables) {
    sb_source_t *s = source(GOLD, SB_SOURCE_ISOTROPIC, 0);
    every_kind(s, s, 0, 4, 10, 5000, "without tables");
    sb_source_destroy(s);
}
