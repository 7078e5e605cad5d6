/* A measured format added from outside the library, as a user adds one:
 * the recipe of docs/architecture.md ("Adding a reader").  A throwaway
 * ".lamb" format (a magic line, then an RGB albedo) is read into a
 * Lambertian source through sb_source_create, registered with
 * sb_measured_register_reader, and factored end to end by the factor job:
 * detection by content, the report naming the format, a snippet that
 * compiles, and the error a constant f_r must give (rank 1: exact at J = 1
 * up to float storage). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"

#define LAMB_MAGIC "#LAMBERT"

/* The reader's source: f_r = albedo / pi above the horizon. */
typedef struct lamb {
    double albedo[3];
} lamb_t;

static int lamb_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const lamb_t *l = self;
    int known = wi[2] > 0 && wo[2] > 0;
    for (int c = 0; c < 3; c++)
        rgb[c] = known ? l->albedo[c] / SB_PI : 0;
    return known;
}

static int lamb_sniff(const unsigned char *head, size_t n) {
    size_t m = strlen(LAMB_MAGIC);
    return n >= m && memcmp(head, LAMB_MAGIC, m) == 0 ? 2 : 0;
}

static sb_result_t lamb_open(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                             sb_measured_info_t *info) {
    (void)o;
    FILE *fp = fopen(path, "r");
    if (!fp) return SB_ERR_IO;
    char magic[16];
    lamb_t *l = malloc(sizeof *l);
    int n = l ? fscanf(fp, "%15s %lf %lf %lf", magic, &l->albedo[0], &l->albedo[1], &l->albedo[2]) : 0;
    fclose(fp);
    if (n != 4) {
        free(l);
        return l ? SB_ERR_FORMAT : SB_ERR_NOMEM;
    }
    static const sb_source_ops_t ops = {lamb_eval, free};
    info->rows = info->samples = 1;
    info->channels = 3;
    for (int c = 0; c < 3; c++)
        info->value_min[c] = info->value_max[c] = info->value_mean[c] = l->albedo[c] / SB_PI;
    return sb_source_create(ctx, &ops, l, SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL | SB_SOURCE_MEASURED,
                            "Lambertian table", out);
}

static const sb_measured_reader_t lamb_reader = {"lamb", "Lambertian albedo (test)", ".lamb", lamb_sniff, lamb_open};

/* Registered, the reader is a row of the registry like the built-in ones. */
SB_TEST(register_lists) {
    size_t before = sb_measured_format_count();
    CHECK(sb_measured_register_reader(&lamb_reader) == SB_OK);
    CHECK(sb_measured_format_count() == before + 1);
    CHECK(strcmp(sb_measured_format_name(before), "lamb") == 0);
    CHECK(strcmp(sb_measured_format_exts(before), ".lamb") == 0);
    CHECK(sb_measured_format_name(before + 1) == NULL);
    /* refused: a name taken (built-in or added), "auto", missing parts */
    CHECK(sb_measured_register_reader(&lamb_reader) == SB_ERR_ARG);
    sb_measured_reader_t bad = lamb_reader;
    bad.name = sb_measured_format_name(0);
    CHECK(sb_measured_register_reader(&bad) == SB_ERR_ARG);
    bad.name = "auto";
    CHECK(sb_measured_register_reader(&bad) == SB_ERR_ARG);
    bad.name = "lamb2";
    bad.open = NULL;
    CHECK(sb_measured_register_reader(&bad) == SB_ERR_ARG);
    CHECK(sb_measured_register_reader(NULL) == SB_ERR_ARG);
    CHECK(sb_measured_format_count() == before + 1);
    /* the registry holds 16 added readers, then says so */
    static char names[16][8];
    sb_result_t r = SB_OK;
    for (int k = 0; k < 16 && r == SB_OK; k++) {
        snprintf(names[k], sizeof names[k], "x%d", k);
        bad = lamb_reader;
        bad.name = names[k];
        r = sb_measured_register_reader(&bad);
    }
    CHECKF(r == SB_ERR_RANGE, "the 17th added reader gave %s", sb_result_name(r));
}

/* Detected by its content (any file name), factored, reported, shaded. */
SB_TEST(factor_end_to_end) {
    CHECK(sb_measured_register_reader(&lamb_reader) == SB_OK);
    const char *dir = sb_tmpdir("extend-reader");
    char table[4200], out[4200];
    snprintf(table, sizeof table, "%s/albedo.txt", dir); /* no .lamb: the magic decides */
    snprintf(out, sizeof out, "%s/set", dir);
    FILE *fp = fopen(table, "w");
    CHECK(fp != NULL);
    if (!fp) return;
    fprintf(fp, "%s\n0.5 0.4 0.3\n", LAMB_MAGIC);
    fclose(fp);

    sb_measured_info_t info;
    sb_source_t *src = NULL;
    CHECK(sb_measured_open(NULL, table, NULL, &src, &info) == SB_OK);
    CHECK(src && strcmp(info.format, "lamb") == 0);
    double wi[3] = {0, 0.6, 0.8}, wo[3] = {0.6, 0, 0.8}, rgb[3];
    CHECK(sb_source_eval(src, wi, wo, rgb) == 1);
    CHECK_REL(rgb[1], 0.4 / SB_PI, 1e-15);
    sb_source_destroy(src);

    sb_job_opts_t o = {0};
    o.source = table;
    o.param = "iso";
    o.res = 8;
    o.terms = 2;
    o.out = out;
    sb_job_t *job = NULL;
    sb_result_t r = sb_job_run(NULL, &o, &job);
    CHECKF(r == SB_OK, "sb_job_run: %s", sb_result_name(r));
    if (r != SB_OK) return;
    /* f_r constant: one term holds it all, up to float textures */
    double e1 = sb_job_headline(job, 1);
    CHECKF(e1 >= 0 && e1 < 1e-5, "headline at J = 1: %g (rank 1 expected)", e1);
    sb_job_destroy(job);

    char path[4300];
    snprintf(path, sizeof path, "%s/report.json", out);
    char *report = sb_read_file(path, NULL);
    CHECKF(report && strstr(report, "\"format\": \"lamb\""), "%s does not name the format", path);
    free(report);
    snprintf(path, sizeof path, "%s/g_00.exr", out);
    CHECKF(sb_file_exists(path), "%s missing", path);
    if (sb_run("command -v glslangValidator", NULL, 0) != 0) SKIP("glslangValidator not installed (glslang-tools)");
    char frag[4300], cmd[9000], log[4096];
    snprintf(frag, sizeof frag, "%s/test.frag", dir);
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", out);
    char *snippet = sb_read_file(path, NULL);
    CHECKF(snippet != NULL, "%s missing", path);
    fp = snippet ? fopen(frag, "w") : NULL;
    if (!fp) {
        free(snippet);
        return;
    }
    fprintf(fp,
            "#version 330 core\n%s\nin vec3 vL;\nin vec3 vV;\nout vec4 color;\n"
            "void main() { color = vec4(sb_brdf(normalize(vL), normalize(vV)), 1.0); }\n",
            snippet);
    fclose(fp);
    free(snippet);
    snprintf(cmd, sizeof cmd, "glslangValidator %s", frag);
    CHECKF(sb_run(cmd, log, sizeof log) == 0, "the snippet does not compile:\n%s", log);
}
