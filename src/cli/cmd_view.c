/* sepbrdf view: an interactive viewer page (index.html) for a factor folder. */
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "pipeline.h"
#include "sepbrdf/viewer.h"

#define DEFAULT_DIR "sepbrdf-out"

typedef struct view_opts {
    const char *dir, *out, *source;
    int no_original;
    sb_measured_opts_t mo;
} view_opts_t;

static const cli_option_t view_only[] = {
    {NULL, "--source", "SPEC", "the original to compare with", cli_set_string, offsetof(view_opts_t, source), 0, 0,
     CLI_OWN},
    {NULL, "--no-original", NULL, "leave the original out (a smaller page)", cli_set_flag,
     offsetof(view_opts_t, no_original), 0, 0, CLI_OWN},
    {0},
};

static void help(void) {
    printf("usage: sepbrdf view [DIR] [OPTIONS]\n"
           "\n"
           "Write DIR/index.html, one self-contained page (WebGL2, no network, opens from\n"
           "file://) that runs DIR/sepbrdf.glsl on a lit sphere and on a plane seen at a\n"
           "grazing angle: the light follows the mouse, sliders set the exposure and the\n"
           "number of terms J; the original, the reconstruction and an error heat map side\n"
           "by side; polar plots of the in-plane slice f(theta_o) for a chosen theta_i,\n"
           "original against every J; the numbers of report.json.\n"
           "\n"
           "DIR     a folder written by `sepbrdf factor` (default ./" DEFAULT_DIR ").\n"
           "        The original is --source, else SOURCE as factor was given it\n"
           "        (report.json), else the source the EXR files record; it is sampled\n"
           "        into a table embedded in the page.  Without one the page shows the\n"
           "        reconstruction only.\n"
           "\n"
           "options:\n"
           "  -o, --out FOLDER     where index.html goes, created if missing (default DIR);\n"
           "                       published as one output set beside the factors (as\n"
           "                       `sepbrdf render` adds its set)\n");
    cli_table_help(view_only, CLI_OWN);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP "\n" CLI_EXIT_HELP);
}

/* Returns an exit code, or -1 to go on. */
static int parse(int argc, char **argv, view_opts_t *o) {
    cli_parser_t p = {.cmd = "view",
                      .help = help,
                      .out_what = "folder",
                      .out = &o->out,
                      .tables = {{view_only, CLI_OWN, o, NULL}},
                      .measured = &o->mo,
                      .what = "DIR",
                      .args = &o->dir,
                      .max_args = 1};
    int rc = cli_parse(argc, argv, &p);
    if (rc < 0 && o->source && o->no_original) {
        cli_error("view", "--source and --no-original contradict each other");
        return EXIT_USAGE;
    }
    return rc;
}

/* The whole of a small text file (64 MiB at most, a regular file),
 * malloc'ed; NULL when unreadable. */
static char *read_text(const char *dir, const char *name) {
    char path[4200], *s = NULL;
    size_t n;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return cli_read_file(path, (size_t)1 << 26, &s, &n) == 0 ? s : NULL;
}

/* Bytes of the folder's g_JJ.exr and h_JJ.exr. */
static size_t texture_bytes(const char *dir, size_t terms) {
    size_t sum = 0;
    for (size_t j = 0; j < terms; j++)
        for (int side = 0; side < 2; side++) {
            char name[64], path[4200];
            struct stat st;
            sb_exr_name(side, j, name, sizeof name);
            snprintf(path, sizeof path, "%s/%s", dir, name);
            if (stat(path, &st) == 0) sum += (size_t)st.st_size;
        }
    return sum;
}

/* The original: --source (must open), else the report's source_spec, else
 * the factors' source description (either may fail: then none, said at
 * level 1).  Returns an exit code, or -1 to go on; *src may stay NULL. */
static int open_original(sb_context_t *ctx, const view_opts_t *o, const sb_factors_t *f, sb_source_t **src) {
    if (o->no_original) return -1;
    if (o->source) {
        sb_result_t r = sb_job_source_open(ctx, o->source, &o->mo, src);
        return r == SB_OK ? -1 : cli_fail("view", ctx, r);
    }
    char given[4096];
    const char *meta = sb_factors_get_meta(f, "source");
    if (cli_read_source_spec(o->dir, given, sizeof given) == 0 && sb_job_source_open(ctx, given, &o->mo, src) == SB_OK)
        return -1;
    if (meta && sb_job_source_open(ctx, meta, &o->mo, src) == SB_OK) return -1;
    cli_info(1,
             "sepbrdf view: %s: its source cannot be opened, the page shows the reconstruction only (name the "
             "original with --source)",
             o->dir);
    return -1;
}

static int write_page(sb_context_t *ctx, const view_opts_t *o) {
    sb_factors_t *f = NULL;
    sb_param_t *param = NULL;
    sb_source_t *src = NULL;
    sb_form_t form;
    char *glsl = NULL, *report = NULL;
    int rc = -1;
    sb_result_t r;
    char g[4200];
    struct stat st;
    snprintf(g, sizeof g, "%s/g_00.exr", o->dir);
    if (stat(o->dir, &st) == 0 && S_ISDIR(st.st_mode) && stat(g, &st) != 0) { /* a render's folder, or any other */
        snprintf(g, sizeof g, "%s/render.json", o->dir);
        cli_error("view", "%s: no factors in it (no g_00.exr)%s: view shows a folder `sepbrdf factor` wrote", o->dir,
                  stat(g, &st) == 0 ? "; it is a folder `sepbrdf render` wrote (its PNGs are the images)" : "");
        return EXIT_IO;
    }
    if ((r = sb_factors_read_exr(ctx, o->dir, &f)) != SB_OK || (r = sb_factors_param(ctx, f, &param, &form)) != SB_OK) {
        rc = cli_fail("view", ctx, r);
        goto out;
    }
    if (!(glsl = read_text(o->dir, "sepbrdf.glsl"))) {
        cli_error("view", "%s/sepbrdf.glsl: cannot read (a folder written by `sepbrdf factor` has it)", o->dir);
        rc = EXIT_IO;
        goto out;
    }
    report = read_text(o->dir, "report.json");
    if ((rc = open_original(ctx, o, f, &src)) >= 0) goto out;
    sb_viewer_opts_t vo = {src, glsl, report, texture_bytes(o->dir, sb_factors_terms(f)), 0};
    /* The page is an output set of its own in the folder (outset.h) */
    char path[4200];
    sb_outset_t *set = cli_outset_begin(ctx, "view", o->out, &rc);
    if (!set) goto out;
    if (cli_set_file(set, "index.html", path, sizeof path) != 0) {
        cli_error("view", "%s/index.html: name too long", o->out);
        rc = EXIT_IO;
    } else if ((r = sb_viewer_write(ctx, path, f, param, form, &vo)) != SB_OK) {
        rc = cli_fail("view", ctx, r);
    }
    int end = cli_outset_end(ctx, "view", set, rc < 0); /* publishes, or discards after a failure */
    if (rc < 0) rc = end;
    if (rc == EXIT_OK && g_verbosity >= 1)
        printf("sepbrdf view: wrote %s/index.html (%s, %zu terms%s%s); open it in a browser with WebGL2\n", o->out,
               sb_param_spec(param), sb_factors_terms(f), src ? ", original " : ", no original",
               src ? sb_source_description(src) : "");
out:
    free(glsl);
    free(report);
    sb_source_destroy(src);
    sb_param_destroy(param);
    sb_factors_destroy(f);
    return rc;
}

int cmd_view(int argc, char **argv) {
    view_opts_t o;
    memset(&o, 0, sizeof o);
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    if (!o.dir) o.dir = DEFAULT_DIR;
    struct stat st;
    if (stat(o.dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        cli_error("view", "%s: not a folder (give a folder written by `sepbrdf factor`)", o.dir);
        return EXIT_IO;
    }
    if (!o.out) o.out = o.dir;
    if ((rc = cli_check_outdir("view", "--out", o.out)) != EXIT_OK) return rc;
    sb_context_t *ctx = NULL;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("view", "out of memory");
        return EXIT_IO;
    }
    rc = write_page(ctx, &o);
    sb_context_destroy(ctx);
    return rc;
}
