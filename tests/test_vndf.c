/* The vndf layout: an RGL file's own grid.  Its matrix holds the file's
 * colour nodes, so J = (theta_i slices) terms reproduce the file wherever
 * it is evaluated, checked against the RGL reader's own evaluation (itself
 * checked against the reference loader in test_measured_rgl.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define PAPER SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf"
#define ORANGE SB_MEASURED_DIR "/rgl_chm_orange_rgb.bsdf"

static sb_param_kind_t vndf_kind(void) {
    sb_param_kind_t k = SB_PARAM_NONE;
    CHECK(sb_param_kind_parse("vndf", &k) == SB_OK);
    return k;
}

static sb_source_t *open_rgl(const char *path) {
    sb_source_t *src = NULL;
    CHECK(sb_measured_open(NULL, path, NULL, &src, NULL) == SB_OK);
    CHECK(sb_source_flags(src) & SB_SOURCE_TABLES);
    return src;
}

static sb_param_t *vndf_of(const sb_source_t *src) {
    sb_param_opts_t po = {0};
    po.tables = sb_source_layout_tables(src);
    sb_param_t *p = NULL;
    CHECK(sb_param_create(NULL, vndf_kind(), &po, &p) == SB_OK);
    return p;
}

/* A pair uniform in solid angle on both hemispheres. */
static void random_pair(double wi[3], double wo[3]) {
    for (int k = 0; k < 2; k++) {
        double *w = k ? wo : wi, z = (double)rand() / RAND_MAX, phi = 2 * SB_PI * rand() / RAND_MAX;
        double s = sqrt(1 - z * z);
        w[0] = s * cos(phi), w[1] = s * sin(phi), w[2] = z;
    }
}

/* f cos theta_i of the factors against the file's evaluation: relative L2
 * over n random pairs; graze > 0: cos theta_i uniform in (0, graze), the
 * light within the snippet's grazing guard (it divides f cos theta_i by
 * max(cos theta_i, 0.001), which the layout's gain undoes). */
static double rel_error(const sb_source_t *src, const sb_factors_t *f, const sb_param_t *p, size_t J, int n,
                        double graze) {
    double num = 0, den = 0;
    srand(7);
    for (int i = 0; i < n; i++) {
        double wi[3], wo[3], t[3], r[3];
        random_pair(wi, wo);
        if (graze > 0) {
            double z = graze * ((double)rand() + 0.5) / ((double)RAND_MAX + 1), s = sqrt(1 - z * z);
            double rho = hypot(wi[0], wi[1]);
            wi[0] = rho > 0 ? s * wi[0] / rho : s, wi[1] = rho > 0 ? s * wi[1] / rho : 0, wi[2] = z;
        }
        sb_source_eval(src, wi, wo, t);
        sb_factors_eval(f, p, SB_FORM_COS, J, wi, wo, r);
        for (int c = 0; c < 3; c++) {
            num += (t[c] - r[c]) * (t[c] - r[c]) * wi[2] * wi[2];
            den += t[c] * t[c] * wi[2] * wi[2];
        }
    }
    return sqrt(num / den);
}

SB_TEST(exact_at_full_rank) {
    const char *files[2] = {PAPER, ORANGE};
    for (int k = 0; k < 2; k++) {
        sb_source_t *src = open_rgl(files[k]);
        sb_param_t *p = vndf_of(src);
        size_t n = sb_param_rows(p);
        CHECK(n >= 2 && sb_param_cols(p) >= 4);
        sb_matrix_opts_t mo = {0};
        mo.form = SB_FORM_COS;
        sb_matrix_t m = {0};
        CHECK(sb_matrix_build(NULL, src, p, &mo, &m) == SB_OK);
        CHECK(m.mask == NULL); /* every node is known, lights below the horizon too */
        sb_plan_opts_t pl = {0};
        pl.terms = n;
        sb_plan_t *plan = NULL;
        sb_factors_t *f = NULL;
        CHECK(sb_plan_create_for(NULL, &m, &pl, &plan) == SB_OK);
        CHECK(sb_plan_execute(plan, &m, p, &f) == SB_OK);
        sb_plan_destroy(plan);
        double full = rel_error(src, f, p, n, 20000, 0), half = rel_error(src, f, p, n / 2, 20000, 0);
        double graze = rel_error(src, f, p, n, 4000, 0.001);
        CHECKF(full < 1e-4, "%s: rank %zu error %g", files[k], n, full);
        CHECKF(graze < 1e-4, "%s: rank %zu error %g with cos theta_i below 0.001", files[k], n, graze);
        CHECKF(half > 10 * full, "%s: %zu terms %g not above the full rank's %g", files[k], n / 2, half, full);
        sb_factors_destroy(f);
        sb_matrix_free(&m);
        sb_param_destroy(p);
        sb_source_destroy(src);
    }
}

SB_TEST(tables_round_trip) {
    sb_source_t *src = open_rgl(PAPER);
    sb_param_t *p = vndf_of(src);
    size_t w, h;
    float *rgb = NULL;
    CHECK(sb_param_tables_texture(p, &w, &h, &rgb) == SB_OK);
    sb_layout_tables_t *t = NULL;
    CHECK(sb_layout_tables_from_texture(NULL, w, h, rgb, &t) == SB_OK);
    sb_param_opts_t po = {0};
    po.tables = t;
    sb_param_t *q = NULL;
    CHECK(sb_param_create(NULL, vndf_kind(), &po, &q) == SB_OK);
    sb_layout_tables_destroy(t);
    CHECK(strcmp(sb_param_spec(p), sb_param_spec(q)) == 0 && strcmp(sb_param_glsl(p), sb_param_glsl(q)) == 0);
    srand(3);
    for (int i = 0; i < 2000; i++) {
        double wi[3], wo[3], a[4], b[4];
        random_pair(wi, wo);
        CHECK(sb_param_coords(p, wi, wo, a, a + 2) == sb_param_coords(q, wi, wo, b, b + 2));
        for (int c = 0; c < 4; c++)
            CHECK(a[c] == b[c]);
        CHECK(sb_param_gain(p, wi, wo) == sb_param_gain(q, wi, wo));
    }
    /* a texture that is not one: the header's slice count changed */
    rgb[3 * (h - 1) * w] += 1;
    CHECK(sb_layout_tables_from_texture(NULL, w, h, rgb, &t) == SB_ERR_FORMAT);
    free(rgb);
    sb_param_destroy(q);
    sb_param_destroy(p);
    sb_source_destroy(src);
}

SB_TEST(needs_tables) {
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    sb_param_t *p = NULL;
    CHECK(sb_param_create(ctx, vndf_kind(), NULL, &p) == SB_ERR_UNSUPPORTED && !p);
    CHECK(strstr(sb_context_last_error(ctx), "RGL") != NULL);
    CHECK(!sb_param_kind_applies(vndf_kind(), SB_SOURCE_ISOTROPIC));
    CHECK(sb_param_kind_applies(vndf_kind(), SB_SOURCE_ISOTROPIC | SB_SOURCE_TABLES));
    sb_source_t *gold = NULL;
    CHECK(sb_source_open(NULL, "microfacet:base=gold,roughness=0.3", &gold) == SB_OK);
    CHECK(sb_source_layout_tables(gold) == NULL && !(sb_source_flags(gold) & SB_SOURCE_TABLES));
    sb_source_destroy(gold);
    sb_context_destroy(ctx);
    /* asked for on a source without them: the message says what it needs, nothing is written */
    char cmd[4096], out[4096];
    snprintf(cmd, sizeof cmd, "%s factor --param vndf -o /tmp/sb_vndf_none_%d", SB_CLI, (int)getpid());
    CHECK(sb_run(cmd, out, sizeof out) != 0);
    CHECKF(strstr(out, "RGL file's own tables") != NULL, "%s", out);
    snprintf(cmd, sizeof cmd, "test ! -e /tmp/sb_vndf_none_%d", (int)getpid());
    CHECK(sb_run(cmd, NULL, 0) == 0);
}

/* The command a user runs: auto keeps vndf on an RGL file, writes vndf.exr
 * beside the textures, the snippet compiles, and render reads the set. */
SB_TEST(cli_factor_render) {
    char dir[] = "/tmp/sb_vndf_XXXXXX", cmd[4096], out[1 << 14];
    CHECK(mkdtemp(dir) != NULL);
    snprintf(cmd, sizeof cmd, "%s -q factor %s -J 8 -o %s/f", SB_CLI, PAPER, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd, "grep -q '\"param\": \"vndf\"' %s/f/report.json && test -s %s/f/vndf.exr", dir, dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
    static const char *const versions[2] = {"#version 330 core", "#version 300 es"};
    for (int v = 0; v < 2 && sb_run("command -v glslangValidator", NULL, 0) == 0; v++) {
        snprintf(cmd, sizeof cmd,
                 "(echo '%s'; cat %s/f/sepbrdf.glsl; echo 'out vec4 c; void main() { c = "
                 "vec4(sb_brdf(vec3(0.3, 0.1, 0.9), vec3(-0.2, 0.3, 0.8)), 1.0); }') > %s/t.frag && "
                 "glslangValidator %s/t.frag",
                 versions[v], dir, dir, dir);
        CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s: %s", versions[v], out);
    }
    snprintf(cmd, sizeof cmd, "%s -q render %s/f -o %s/r.png", SB_CLI, dir, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
}

/* An RGL file's values are f cos theta_i (SB_SOURCE_STORES_COS): towards
 * the horizon f grows as 1 / cos theta_i while f cos theta_i settles. */
SB_TEST(stores_cos) {
    sb_source_t *src = open_rgl(PAPER);
    CHECK(sb_source_flags(src) & SB_SOURCE_STORES_COS);
    double wo[3] = {0.5, 0, sqrt(0.75)}, fc[3];
    for (int k = 0; k < 3; k++) {
        double eps = pow(10, -2 - 2 * k), wi[3] = {-cos(eps), 0, sin(eps)}, f[3];
        CHECK(sb_source_eval(src, wi, wo, f) == 1);
        fc[k] = f[1] * wi[2];
    }
    /* 0.0076, 0.0048, 0.0048 on paper: f itself 100x from one to the next */
    CHECKF(fc[0] > 0 && fabs(fc[1] / fc[0] - 1) < 0.5 && fabs(fc[2] / fc[1] - 1) < 0.02, "f cos %g %g %g", fc[0], fc[1],
           fc[2]);
    sb_source_destroy(src);
}

/* auto on an RGL file screens vndf first: at J = 8 (the file's slices) it
 * returns the file to float rounding and the other layouts are not
 * screened; at J = 4 it does not, and they are. */
SB_TEST(exact_ends_screening) {
    for (size_t J = 4; J <= 8; J += 4) {
        sb_job_opts_t o = {0};
        o.source = PAPER;
        o.terms = J;
        sb_job_t *job = NULL;
        CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
        if (!job) return;
        CHECK(sb_param_kind(sb_job_param(job)) == vndf_kind());
        size_t skipped = 0, others = 0;
        for (size_t i = 0; i < sb_job_candidate_count(job); i++) {
            const sb_job_candidate_t *c = sb_job_candidate(job, i);
            CHECKF(c->form == SB_FORM_COS, "%s %s: the file's f diverges at the horizon", sb_param_kind_name(c->kind),
                   sb_form_name(c->form));
            if (c->kind == vndf_kind()) continue;
            others++;
            skipped += strncmp(c->why, "not screened", 12) == 0;
        }
        double h = sb_job_headline(job, J);
        CHECKF(others > 0 && skipped == (J == 8 ? others : 0), "J %zu: %zu of %zu not screened, headline %g", J,
               skipped, others, h);
        CHECKF(J == 8 ? h < 1e-6 : h > 1e-3, "J %zu: headline %g", J, h);
        sb_job_destroy(job);
    }
}

/* --shader all keeps vndf (its tables are read in HLSL, MSL and WGSL as in
 * GLSL: auto dropped it there before, and an RGL file got vh's 2.4x the
 * error): the same layout and headline as the GLSL-only run, and the set's
 * HLSL, with its sb_vndf, compiles. */
SB_TEST(shader_all_keeps_vndf) {
    double h[2] = {0, 0};
    for (int all = 0; all < 2; all++) {
        sb_job_opts_t o = {0};
        o.source = ORANGE;
        o.terms = 4;
        o.shaders = all ? "all" : NULL;
        sb_job_t *job = NULL;
        CHECK(sb_job_run(NULL, &o, &job) == SB_OK);
        if (!job) return;
        CHECK(sb_param_kind(sb_job_param(job)) == vndf_kind());
        h[all] = sb_job_headline(job, 4);
        sb_job_destroy(job);
    }
    CHECKF(h[0] > 0 && h[1] == h[0], "headline %g with --shader all, %g GLSL only", h[1], h[0]);
    char dir[] = "/tmp/sb_vndf_XXXXXX", cmd[4096], out[1 << 14];
    CHECK(mkdtemp(dir) != NULL);
    snprintf(cmd, sizeof cmd, "%s -q factor %s -J 4 --shader all -o %s/f", SB_CLI, ORANGE, dir);
    CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd,
             "grep -q '\"param\": \"vndf\"' %s/f/report.json && test -s %s/f/vndf.exr && "
             "grep -q 'Texture2D<float4> sb_vndf' %s/f/sepbrdf.hlsl && grep -q 'texture2d<float> sb_vndf' "
             "%s/f/sepbrdf.metal && grep -q 'var sb_vndf: texture_2d<f32>' %s/f/sepbrdf.wgsl",
             dir, dir, dir, dir, dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    if (sb_run("command -v glslangValidator", NULL, 0) == 0) {
        snprintf(cmd, sizeof cmd,
                 "(cat %s/f/sepbrdf.hlsl; echo 'float4 main(float3 L : TEXCOORD0, float3 V : TEXCOORD1) : "
                 "SV_Target { return float4(sb_brdf(normalize(L), normalize(V)), 1.0); }') > %s/t.hlsl && "
                 "glslangValidator -D -V -S frag -e main -o %s/t.spv %s/t.hlsl",
                 dir, dir, dir, dir);
        CHECKF(sb_run(cmd, out, sizeof out) == 0, "%s", out);
    }
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(sb_run(cmd, NULL, 0) == 0);
}
