/* Extending the library from a program (experimental/layout.h,
 * experimental/solver.h): a layout and a solver written here, registered
 * through the public calls and run end to end by the factor job.  This
 * file is the recipe of docs/extending.md.
 *
 * The layout, "io-eq": the io grid (rows wi, columns wo, cell k = R i_phi
 * + i_theta) with its elevation axis uniform in z = 1 - cos(theta) instead
 * of theta, so every cell has the same solid angle, 2 pi zmax / R^2 with
 * zmax = 1 - cos(theta_max): s = z / zmax, t = phi / 2 pi.
 *
 * The solver, "mine": the truncated SVD through the public svd.h plan
 * with method full, chosen by its name. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/experimental/layout.h"
#include "sepbrdf/experimental/solver.h"
#include "sepbrdf/sepbrdf.h"

/* ---- the layout ---------------------------------------------------------- */

static size_t eq_res(const sb_param_t *p) {
    size_t w = 0;
    sb_param_texture_size(p, SB_SIDE_G, &w, NULL);
    return w;
}
static double eq_zmax(const sb_param_t *p) { return 2 * pow(sin(sb_param_theta_max(p) / 2), 2); }

/* Centre of cell k: z = (i_theta + 1/2) zmax / R, phi = (i_phi + 1/2) 2 pi / R. */
static void eq_dir(const sb_param_t *p, size_t k, double w[3]) {
    size_t R = eq_res(p);
    double z = ((double)(k % R) + 0.5) * eq_zmax(p) / (double)R, phi = ((double)(k / R) + 0.5) * 2 * SB_PI / (double)R;
    double s = sqrt(z * (2 - z));
    w[0] = s * cos(phi), w[1] = s * sin(phi), w[2] = 1 - z;
}
static int eq_cell_dirs(const sb_param_t *p, size_t row, size_t col, double wi[3], double wo[3]) {
    eq_dir(p, row, wi);
    eq_dir(p, col, wo);
    return 1;
}
static double eq_measure(const sb_param_t *p, size_t k) {
    (void)k;
    double R = (double)eq_res(p);
    return 2 * SB_PI * eq_zmax(p) / (R * R);
}
/* z = |w_xy|^2 / (1 + w_z) = 1 - cos(theta), accurate near the pole. */
static void eq_st(const sb_param_t *p, const double w[3], double st[2]) {
    double phi = atan2(w[1], w[0]);
    if (phi < 0) phi += 2 * SB_PI;
    st[0] = (w[0] * w[0] + w[1] * w[1]) / (1 + w[2]) / eq_zmax(p);
    st[1] = phi / (2 * SB_PI);
}
static int eq_coords(const sb_param_t *p, const double wi[3], const double wo[3], double st_g[2], double st_h[2]) {
    if (wi[2] <= 0 || wo[2] <= 0) return 0;
    eq_st(p, wi, st_g);
    eq_st(p, wo, st_h);
    return st_g[0] <= 1 && st_h[0] <= 1;
}
static void eq_row_sample(const sb_param_t *p, size_t row, const double u[2], double w[3]) {
    size_t R = eq_res(p);
    double z = ((double)(row % R) + u[0]) * eq_zmax(p) / (double)R;
    double phi = ((double)(row / R) + u[1]) * 2 * SB_PI / (double)R, s = sqrt(fmax(z * (2 - z), 0));
    w[0] = s * cos(phi), w[1] = s * sin(phi), w[2] = 1 - z;
}

static const sb_layout_vt_t eq_vt = {
    eq_cell_dirs,
    eq_measure,
    eq_measure,
    eq_coords,
    "// io-eq: s = (1 - cos theta) / (1 - cos SB_THETA_MAX) (clamp), t = phi / 2pi (repeat)\n"
    "vec2 sb_eq_st(vec3 w) {\n"
    "    float zmax = 2.0 * sin(0.5 * SB_THETA_MAX) * sin(0.5 * SB_THETA_MAX);\n"
    "    float phi = atan(w.y, w.x);\n"
    "    if (phi < 0.0) phi += 2.0 * SB_PI;\n"
    "    return vec2(dot(w.xy, w.xy) / (1.0 + w.z) / zmax, phi / (2.0 * SB_PI));\n"
    "}\n"
    "vec4 sb_coords(vec3 L, vec3 V) { return vec4(sb_eq_st(L), sb_eq_st(V)); }\n"
    "bool sb_domain(vec3 L, vec3 V, vec4 st) { return L.z > 0.0 && V.z > 0.0 && st.x <= 1.0 && st.z <= 1.0; }\n",
    NULL,
    NULL}; /* no gain, no cell values (vndf's: layout.h) */

/* A row edge without a row cell: refused (registration). */
static float eq_row_edge(const sb_param_t *p, int axis, size_t i) {
    (void)p, (void)axis;
    return (float)i;
}

static const sb_layout_desc_t eq_layout = {
    .name = "io-eq",
    .description = "the theta-phi grid, uniform in 1 - cos(theta): cells of equal solid angle",
    .keys = "res",
    .caps = SB_CAP_SEPARABLE,
    .wrap_y = SB_WRAP_REPEAT,
    .vt = &eq_vt,
    .row_sample = eq_row_sample,
    .sample_glsl =
        "// io-eq cell: z = 1 - cos(theta) and phi linear in u\n"
        "vec3 sb_row_dir(ivec2 cell, vec2 u) {\n"
        "    vec2 n = vec2(textureSize(sb_g, 0).xy);\n"
        "    float zmax = 2.0 * sin(0.5 * SB_THETA_MAX) * sin(0.5 * SB_THETA_MAX);\n"
        "    float z = (float(cell.x) + u.x) * zmax / n.x, phi = (float(cell.y) + u.y) * 2.0 * SB_PI / n.y;\n"
        "    float s = sqrt(max(z * (2.0 - z), 0.0));\n"
        "    return vec3(s * cos(phi), s * sin(phi), 1.0 - z);\n"
        "}\n"};

/* ---- the solver ---------------------------------------------------------- */

static sb_result_t mine_plan(sb_context_t *ctx, const sb_solve_problem_t *pb, void **state) {
    sb_svd_opts_t o = pb->svd;
    o.method = SB_METHOD_FULL;
    return sb_svd_create(ctx, pb->rows, pb->cols, pb->terms, &o, (sb_svd_t **)state);
}
static void mine_destroy(void *state) { sb_svd_destroy(state); }
static sb_result_t mine_execute(void *state, const sb_solve_in_t *in, sb_solve_out_t *out) {
    return sb_svd_execute(state, in->x, in->ldx, out->s, out->u, out->v, NULL, NULL);
}
static const sb_solver_t mine_solver = {.name = "mine",
                                        .description = "dgesdd through the public svd.h plan",
                                        .caps = SB_CAP_ORTHONORMAL | SB_CAP_METHOD,
                                        .plan = mine_plan,
                                        .destroy = mine_destroy,
                                        .execute = mine_execute,
                                        .note = "a test's own"};

/* ---- registration ---------------------------------------------------------- */

static sb_param_kind_t eq_kind = SB_PARAM_NONE;
static sb_method_t mine_method = SB_METHOD_NONE;

static int register_both(void) {
    if (eq_kind == SB_PARAM_NONE && sb_param_register(NULL, &eq_layout, &eq_kind) != SB_OK) return 0;
    if (mine_method == SB_METHOD_NONE && sb_solver_register(NULL, &mine_solver, &mine_method) != SB_OK) return 0;
    return 1;
}

/* Registered by name: the next numbers, listed and parsed like the
 * built-in ones; a taken name, a bad name or a missing function is
 * refused and changes nothing. */
SB_TEST(registration) {
    size_t kinds = sb_param_kind_count(), methods = sb_method_count(), solvers = sb_solver_count();
    CHECK(register_both());
    CHECK((size_t)eq_kind == kinds && sb_param_kind_count() == kinds + 1);
    CHECK((size_t)mine_method == methods && sb_method_count() == methods + 1 && sb_solver_count() == solvers + 1);
    sb_param_kind_t k;
    sb_method_t m;
    CHECK(sb_param_kind_parse("io-eq", &k) == SB_OK && k == eq_kind);
    CHECK(sb_method_parse("mine", &m) == SB_OK && m == mine_method);
    CHECK(strcmp(sb_method_note(m), "a test's own") == 0);
    CHECK(strcmp(sb_solver_name(solvers), "mine") == 0 && (sb_solver_caps(solvers) & SB_CAP_METHOD));
    char list[256];
    sb_param_kind_list(list, sizeof list, ",");
    CHECK(strstr(list, ",io-eq") != NULL);
    CHECK(sb_param_kind_parse("io", &k) == SB_OK && k == SB_PARAM_IO); /* the numbered kinds keep their numbers */
    CHECK(sb_method_parse("nmf", &m) == SB_OK && m == SB_METHOD_NMF);
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    CHECK(sb_param_register(ctx, &eq_layout, NULL) == SB_ERR_RANGE);
    CHECK(strstr(sb_context_last_error(ctx), "io-eq") != NULL);
    CHECK(sb_solver_register(ctx, &mine_solver, NULL) == SB_ERR_RANGE);
    sb_layout_desc_t bad = eq_layout;
    bad.name = "io:eq";
    CHECK(sb_param_register(ctx, &bad, NULL) == SB_ERR_ARG);
    bad.name = "eq2";
    bad.vt = NULL;
    CHECK(sb_param_register(ctx, &bad, NULL) == SB_ERR_ARG && sb_param_register(ctx, NULL, NULL) == SB_ERR_ARG);
    bad = eq_layout; /* row cells: row_cell and row_edge both (sampler.h) */
    bad.name = "eq3";
    bad.row_edge = eq_row_edge;
    CHECK(sb_param_register(ctx, &bad, NULL) == SB_ERR_ARG);
    CHECK(strstr(sb_context_last_error(ctx), "row_cell and row_edge") != NULL);
    sb_solver_t worse = mine_solver;
    worse.name = "auto";
    CHECK(sb_solver_register(ctx, &worse, NULL) == SB_ERR_ARG);
    worse.name = "mine2";
    worse.caps = 0; /* neither takes nor a method */
    CHECK(sb_solver_register(ctx, &worse, NULL) == SB_ERR_ARG && sb_solver_register(ctx, NULL, NULL) == SB_ERR_ARG);
    CHECK(sb_param_kind_count() == kinds + 1 && sb_solver_count() == solvers + 1);
    sb_context_destroy(ctx);
}

/* A layout whose init gives the shape itself (sb_param_set_shape): the
 * io-eq grid again, its spec and wraps set by hand, and one that gives
 * none. */
static sb_result_t eq2_init(sb_context_t *ctx, sb_param_t *p) {
    size_t R = sb_param_options(p)->res;
    char spec[64];
    snprintf(spec, sizeof spec, "io-eq2:res=%zu", R);
    sb_layout_shape_t s = {{R, R}, {R, R}, {SB_WRAP_CLAMP, SB_WRAP_REPEAT}, {SB_WRAP_CLAMP, SB_WRAP_REPEAT}, spec};
    return sb_param_set_shape(ctx, p, &s);
}
static sb_result_t none_init(sb_context_t *ctx, sb_param_t *p) {
    (void)ctx, (void)p;
    return SB_OK;
}

SB_TEST(layout_init) {
    static sb_layout_desc_t eq2, none;
    eq2 = eq_layout, none = eq_layout;
    eq2.name = "io-eq2", eq2.init = eq2_init;
    none.name = "io-none", none.init = none_init;
    sb_param_kind_t k2, kn;
    CHECK(sb_param_register(NULL, &eq2, &k2) == SB_OK && sb_param_register(NULL, &none, &kn) == SB_OK);
    sb_param_opts_t po = {.res = 5};
    sb_param_t *p = NULL, *q = NULL;
    CHECK(sb_param_create(NULL, k2, &po, &p) == SB_OK && sb_param_create(NULL, SB_PARAM_IO, &po, &q) == SB_OK);
    if (!p || !q) return;
    CHECK(strcmp(sb_param_spec(p), "io-eq2:res=5") == 0 && sb_param_rows(p) == 25 && sb_param_cols(p) == 25);
    for (int side = 0; side < 2; side++) { /* the io grid's textures and wraps */
        size_t w[2], h[2];
        int wp[2], wq[2];
        sb_param_texture_size(p, side, &w[0], &h[0]);
        sb_param_texture_size(q, side, &w[1], &h[1]);
        sb_param_wrap(p, side, wp);
        sb_param_wrap(q, side, wq);
        CHECK(w[0] == w[1] && h[0] == h[1] && wp[0] == wq[0] && wp[1] == wq[1]);
    }
    sb_layout_shape_t s = {{5, 5}, {5, 5}, {0, 0}, {0, 0}, "io-eq2"};
    CHECK(sb_param_set_shape(NULL, p, &s) == SB_ERR_ARG); /* outside init */
    CHECK(sb_param_options(NULL) == NULL && sb_param_options(p)->res == 5);
    sb_param_destroy(p);
    sb_param_destroy(q);
    sb_context_t *ctx = NULL;
    CHECK(sb_context_create(&ctx) == SB_OK);
    CHECK(sb_param_create(ctx, kn, &po, &p) == SB_ERR_ARG && p == NULL);
    CHECK(strstr(sb_context_last_error(ctx), "no shape") != NULL);
    sb_context_destroy(ctx);
}

/* The layout's geometry as the library serves it: the row measures sum
 * to the cap's solid angle, each cell's centre maps into its own texel,
 * and a row sample stays in its cell. */
SB_TEST(layout_geometry) {
    CHECK(register_both());
    sb_param_t *p = NULL;
    sb_param_kind_t k;
    sb_param_opts_t po = {0};
    CHECK(sb_param_parse_spec(NULL, "io-eq:res=6,theta_max=80", &k, &po) == SB_OK && k == eq_kind);
    CHECK(sb_param_create(NULL, k, &po, &p) == SB_OK);
    if (!p) return;
    CHECK(strcmp(sb_param_spec(p), "io-eq:res=6,theta_max=80") == 0 && strcmp(sb_param_name(p), "io-eq") == 0);
    size_t R = 6, rows = sb_param_rows(p);
    CHECK(rows == R * R && sb_param_cols(p) == R * R && sb_param_kind(p) == eq_kind);
    double sum = 0, tmax = 80 * SB_PI / 180;
    for (size_t r = 0; r < rows; r++)
        sum += sb_param_row_measure(p, r);
    CHECK_REL(sum, 2 * SB_PI * (1 - cos(tmax)), 1e-12);
    for (size_t r = 0; r < rows; r++) {
        double wi[3], wo[3], stg[2], sth[2], u[2] = {0.25, 0.75}, w[3];
        CHECK(sb_param_cell_dirs(p, r, rows - 1 - r, wi, wo) == 1 && sb_param_coords(p, wi, wo, stg, sth) == 1);
        CHECK((size_t)(stg[0] * R) + R * (size_t)(stg[1] * R) == r);
        CHECK((size_t)(sth[0] * R) + R * (size_t)(sth[1] * R) == rows - 1 - r);
        CHECK(sb_param_row_sample(p, r, u, w) == 1 && sb_param_coords(p, w, wo, stg, sth) == 1);
        CHECK((size_t)(stg[0] * R) + R * (size_t)(stg[1] * R) == r);
    }
    sb_param_destroy(p);
}

static char *slurp(const char *path) {
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    fclose(fp);
    buf[n] = 0;
    return buf;
}

/* The factor job on the registered layout with the registered solver:
 * the same terms as method full (both are dgesdd on the same matrix),
 * the output set written, its snippet compiling as a fragment shader and
 * report.json naming both. */
SB_TEST(end_to_end) {
    CHECK(register_both());
    sb_job_opts_t o = {0};
    o.source = "cook-torrance:roughness=0.3";
    o.param = "io-eq";
    o.res = 8;
    o.terms = 2;
    sb_job_t *mine = NULL, *full = NULL;
    o.method = mine_method;
    sb_result_t r = sb_job_run(NULL, &o, &mine);
    CHECKF(r == SB_OK, "mine: %s", sb_result_name(r));
    o.method = SB_METHOD_FULL;
    CHECK(sb_job_run(NULL, &o, &full) == SB_OK);
    if (!mine || !full) return;
    for (size_t j = 0; j < 2; j++)
        for (int c = 0; c < 3; c++)
            CHECK_REL(sb_factors_sigma(sb_job_factors(mine), j, c), sb_factors_sigma(sb_job_factors(full), j, c),
                      1e-12);
    CHECK_REL(sb_job_headline(mine, 2), sb_job_headline(full, 2), 1e-9);
    CHECK(sb_job_headline(mine, 2) < sb_job_headline(mine, 1));
    const char *dir = sb_tmpdir("extend");
    CHECK(sb_job_write(NULL, mine, dir) == SB_OK);
    char path[1200], cmd[2600], log[4096];
    snprintf(path, sizeof path, "%s/report.json", dir);
    const char *js = slurp(path);
    CHECKF(js && strstr(js, "\"method\": \"mine\"") && strstr(js, "\"param_spec\": \"io-eq:res=8\""), "%s",
           js ? js : "no report.json");
    snprintf(path, sizeof path, "%s/g_00.exr", dir);
    CHECK(sb_file_exists(path));
    if (sb_run("command -v glslangValidator", NULL, 0) != 0) {
        sb_job_destroy(mine);
        sb_job_destroy(full);
        SKIP("glslangValidator not installed (Debian package glslang-tools)");
    }
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", dir);
    char *glsl = strdup(slurp(path) ? slurp(path) : "");
    CHECK(strstr(glsl, "sb_eq_st") != NULL);
    snprintf(path, sizeof path, "%s/test.frag", dir);
    FILE *fp = fopen(path, "w");
    if (fp) {
        fprintf(fp,
                "#version 330 core\n%s\nin vec3 vL;\nin vec3 vV;\nout vec4 color;\n"
                "void main() { color = vec4(sb_brdf(normalize(vL), normalize(vV)), 1.0); }\n",
                glsl);
        fclose(fp);
    }
    snprintf(cmd, sizeof cmd, "glslangValidator %s", path);
    int rc = sb_run(cmd, log, sizeof log);
    CHECKF(rc == 0, "glslangValidator failed:\n%s", log);
    free(glsl);
    sb_job_destroy(mine);
    sb_job_destroy(full);
}

/* A layout without a sampler (a program's own: every built-in layout has
 * one since rv's): `--method nmf` writes the set without sampler.bin, and
 * the run's warning says why (issue 38, item 3; was test_nmf.c's
 * no_sampler_says_why on rv). */
SB_TEST(nmf_without_sampler_said) {
    static sb_layout_desc_t plain;
    plain = eq_layout;
    plain.name = "io-eq-plain", plain.row_sample = NULL, plain.sample_glsl = NULL;
    sb_param_kind_t k;
    CHECK(sb_param_register(NULL, &plain, &k) == SB_OK);
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_job_opts_t o = {0};
    o.param = "io-eq-plain", o.res = 6, o.terms = 1, o.method = SB_METHOD_NMF;
    sb_job_t *job = NULL;
    const char *dir = sb_tmpdir("extend-plain");
    CHECKF(sb_job_run(ctx, &o, &job) == SB_OK, "%s", sb_context_last_error(ctx));
    CHECKF(job && sb_job_write(ctx, job, dir) == SB_OK, "write: %s", sb_context_last_error(ctx));
    int said = 0;
    for (size_t i = 0; job && i < sb_job_warning_count(job); i++)
        said |= strstr(sb_job_warning(job, i), "no sampler") && strstr(sb_job_warning(job, i), "io-eq-plain");
    CHECKF(said, "warnings: %s", job && sb_job_warning_count(job) ? sb_job_warning(job, 0) : "none");
    char path[1200];
    snprintf(path, sizeof path, "%s/sampler.bin", dir);
    FILE *fp = fopen(path, "rb");
    CHECKF(!fp, "%s written", path);
    if (fp) fclose(fp);
    sb_job_destroy(job);
    sb_context_destroy(ctx);
}
