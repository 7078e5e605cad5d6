/* sepbrdf render: the original BRDF and its reconstructions on a lit sphere,
 * PNG strips and errors per J. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "pipeline.h"

#define DEFAULT_OUT "sepbrdf-render"
#define MAX_TERMS_LIST 64
#define STR_(x) #x
#define STR(x) STR_(x)

typedef struct render_opts {
    const char *input, *out, *source;
    size_t terms[MAX_TERMS_LIST], nterms;
    sb_job_opts_t job;           /* the factor group's options, for a SOURCE */
    const char *factor_opt_name; /* a SOURCE-only option given, or NULL */
    sb_render_opts_t scene;
    double elev, azim;
    sb_tonemap_t tm;
    double diff_scale;
    const char *exposure_rule; /* "auto" or "peak" when the exposure came from the original, else NULL */
    unsigned dropped;          /* channels of the original left out: the factors hold none (factor --channels) */
} render_opts_t;

static int set_terms(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    render_opts_t *o = dst;
    o->nterms = 0;
    const char *s = v;
    while (1) {
        char item[32];
        size_t n = strcspn(s, ",");
        if (n == 0 || n >= sizeof item) {
            cli_error("render", "--terms '%s' is not a list of integers like 1,2,4", v);
            return -1;
        }
        memcpy(item, s, n);
        item[n] = 0;
        if (o->nterms == MAX_TERMS_LIST) {
            cli_error("render", "--terms: more than %d entries", MAX_TERMS_LIST);
            return -1;
        }
        if (cli_parse_size("render", "--terms", item, 1, (size_t)1 << 30, &o->terms[o->nterms])) return -1;
        o->nterms++;
        if (!s[n]) break;
        s += n + 1;
    }
    return 0;
}

static int set_light(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    (void)cmd, (void)op;
    render_opts_t *o = dst;
    double a[3] = {0, 0, 0};
    int n = 0;
    const char *s = v;
    while (n < 3) {
        char item[64], *end;
        size_t len = strcspn(s, ",");
        if (len == 0 || len >= sizeof item) break;
        memcpy(item, s, len);
        item[len] = 0;
        a[n] = strtod(item, &end);
        if (*end || !isfinite(a[n])) break;
        n++;
        if (!s[len]) {
            s += len;
            break;
        }
        s += len + 1;
    }
    if (n < 2 || *s) {
        cli_error("render", "--light '%s' is not ELEV,AZIM or ELEV,AZIM,E (degrees, irradiance)", v);
        return -1;
    }
    if (a[0] < 0 || a[0] > 90 || a[2] < 0) {
        cli_error("render", "--light '%s': elevation must be in 0..90 and E >= 0", v);
        return -1;
    }
    if (o->scene.light_count >= SB_RENDER_MAX_LIGHTS) {
        cli_error("render", "--light: at most %d lights in all", SB_RENDER_MAX_LIGHTS);
        return -1;
    }
    sb_light_from_angles(a[0], a[1], a[2], &o->scene.lights[o->scene.light_count++]);
    return 0;
}

static int set_exposure(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    double *x = dst;
    if (strcmp(v, "auto") == 0 || strcmp(v, "peak") == 0) {
        *x = v[0] == 'a' ? 0 : -1; /* resolved from the original (render_set) */
        return 0;
    }
    char *end = NULL;
    double e = strtod(v, &end);
    if (end != v && !*end && e >= 1e-6 && e <= 1e6) return cli_parse_double(cmd, op->name, v, 1e-6, 1e6, x);
    cli_error(cmd, "%s '%s': need a number in 1e-06..1e+06 (a factor on radiance), auto or peak", op->name, v);
    return -1;
}

static int set_tonemap(const char *cmd, const cli_option_t *op, const char *v, void *dst) {
    if (sb_tonemap_parse(v, dst) == SB_OK) return 0;
    cli_error(cmd, "%s '%s' unknown, need %s or %s", op->name, v, sb_tonemap_name(SB_TONEMAP_CLAMP),
              sb_tonemap_name(SB_TONEMAP_REINHARD));
    return -1;
}

/* The options of `render` alone (stored into its render_opts_t). */
#define AT(m) offsetof(render_opts_t, m)
static const cli_option_t render_only[] = {
    {"-J", "--terms", "LIST", "numbers of terms to render, e.g. 1,2,4 (default 1,2,4;\nfor DIR every J of the folder)",
     set_terms, 0, 0, 0, CLI_RENDER},
    {NULL, "--source", "SPEC", "the original to compare with (DIR only)", cli_set_string, AT(source), 0, 0, CLI_RENDER},
    {"-s", "--size", "N", "image width and height in pixels, 8..4096 (default 256)", cli_set_size, AT(scene.size), 8,
     4096, CLI_RENDER},
    {NULL, "--light-elev", "DEG",
     "elevation of the light above the image plane, towards\nthe viewer, 0..90 (default 45)", cli_set_double, AT(elev),
     0, 90, CLI_RENDER},
    {NULL, "--light-azim", "DEG", "azimuth in the image plane from right towards up\n(default 45)", cli_set_double,
     AT(azim), -360, 360, CLI_RENDER},
    {NULL, "--light", "EL,AZ[,E]",
     "one more light (repeatable, up to " STR(SB_RENDER_MAX_LIGHTS) " in all), E its\nirradiance (default pi)",
     set_light, 0, 0, 0, CLI_RENDER},
    {NULL, "--exposure", "X|auto",
     "multiply radiance by X before tone mapping; auto\n(default): the original's log-average luminance to 0.18\n"
     "(middle grey; a dark coloured material stays visible);\npeak: 1 / the original's brightest channel",
     set_exposure, AT(tm.exposure), 0, 0, CLI_RENDER},
    {NULL, "--tonemap", "T", "clamp (default) or reinhard (x / (1 + x))", set_tonemap, AT(tm.op), 0, 0, CLI_RENDER},
    {NULL, "--diff-scale", "N", "magnification of the difference panel (default 4)", cli_set_double, AT(diff_scale),
     1e-3, 1e6, CLI_RENDER},
    {0},
};
#undef AT

static void help(void) {
    printf("usage: sepbrdf render [SOURCE | DIR] [OPTIONS]\n"
           "\n"
           "Render a lit sphere with the original BRDF and with its separable\n"
           "reconstruction from J terms, for each J asked, and write into the output folder:\n"
           "  original.png         the original\n"
           "  render_JNN.png       original | reconstruction | difference x diff-scale\n"
           "  render.json          errors per J, settings\n"
           "Prints per J the RMS error of linear radiance and the RMSE and PSNR of the\n"
           "display values (tone mapped, sRGB encoded, in [0, 1]) over the sphere's pixels.\n"
           "\n"
           "SOURCE  MODEL[:key=value,...] or a measured file: factored first, as `sepbrdf\n"
           "        factor` does (default: " SB_JOB_DEFAULT_SOURCE ").\n"
           "DIR     a folder written by `sepbrdf factor`: its factors, parameterisation\n"
           "        and form; the original is --source, else SOURCE as factor was given\n"
           "        it, else the source description (both in the EXR headers).\n"
           "\n"
           "options:\n"
           "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n");
    cli_table_help(render_only, CLI_RENDER);
    printf("options of `sepbrdf factor`, for a SOURCE only (the same defaults; J is the\n"
           "largest of --terms):\n");
    cli_table_help(cli_factor_options, CLI_RENDER);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP
           "\n"
           "Scene: unit sphere, orthographic camera looking down -z, tangent frame\n"
           "t = normalize(dP/dphi) of the sphere with its pole up (see docs/rendering.md);\n"
           "radiance = sum over lights of f_r(L, V) E cos(theta_L), E = pi by default.\n"
           "With --scene lights=EL,AZ/..., the fit is made for those lights and they\n"
           "replace --light-elev, --light-azim and --light.\n"
           "\n" CLI_EXIT_HELP);
}

static int parse(int argc, char **argv, render_opts_t *o) {
    cli_parser_t p = {
        .cmd = "render",
        .help = help,
        .out_what = "folder",
        .out = &o->out,
        .tables = {{render_only, CLI_RENDER, o, NULL}, {cli_factor_options, CLI_RENDER, &o->job, &o->factor_opt_name}},
        .measured = &o->job.measured,
        .what = "SOURCE or DIR",
        .args = &o->input,
        .max_args = 1};
    return cli_parse(argc, argv, &p); /* -1: go on */
}

static int is_dir(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

/* original.png (b NULL) or a strip, into the output set. */
static sb_result_t write_png(sb_context_t *ctx, sb_outset_t *set, const char *name, const sb_image_t *a,
                             const sb_image_t *b, const render_opts_t *o) {
    char path[4200];
    if (cli_set_file(set, name, path, sizeof path) != 0)
        return sb_error(ctx, SB_ERR_IO, "%s/%s: name too long", sb_outset_target(set), name);
    return b ? sb_image_write_strip_png(ctx, path, a, b, &o->tm, o->diff_scale)
             : sb_image_write_png(ctx, path, a, &o->tm);
}

static void write_json(json_t *j, const render_opts_t *o, const sb_source_t *src, const sb_param_t *param,
                       sb_form_t form, const sb_image_diff_t *d, char names[][32]) {
    json_begin_object(j, NULL);
    json_string(j, "sepbrdf_version", sb_version());
    json_string(j, "command", "render");
    json_string(j, "source", sb_source_description(src));
    json_string(j, "param_spec", sb_param_spec(param));
    json_string(j, "form", sb_form_name(form));
    json_begin_array(j, "channels"); /* compared: those the factors hold */
    for (int c = 0; c < 3; c++)
        if (!(o->dropped >> c & 1)) json_string(j, NULL, (const char *[]){"R", "G", "B"}[c]);
    json_end_array(j);
    json_int(j, "size", (long long)o->scene.size);
    json_begin_array(j, "lights");
    for (size_t i = 0; i < o->scene.light_count; i++) {
        json_begin_object(j, NULL);
        json_begin_array(j, "dir");
        for (int k = 0; k < 3; k++)
            json_number(j, NULL, o->scene.lights[i].dir[k]);
        json_end_array(j);
        json_number(j, "irradiance", o->scene.lights[i].irradiance > 0 ? o->scene.lights[i].irradiance : SB_PI);
        json_end_object(j);
    }
    json_end_array(j);
    json_string(j, "tonemap", sb_tonemap_name(o->tm.op));
    json_number(j, "exposure", o->tm.exposure);
    json_string(j, "exposure_rule", o->exposure_rule ? o->exposure_rule : "given");
    json_number(j, "diff_scale", o->diff_scale);
    json_string(j, "psnr_on",
                "display values in [0, 1] (exposure, tone map, sRGB OETF), sphere pixels; null = identical");
    json_begin_array(j, "results");
    for (size_t k = 0; k < o->nterms; k++) {
        json_begin_object(j, NULL);
        json_int(j, "terms", (long long)o->terms[k]);
        json_int(j, "pixels", (long long)d[k].pixels);
        json_number(j, "rmse_linear", d[k].rmse_linear);
        json_number(j, "max_abs_linear", d[k].max_linear);
        json_number(j, "rmse", d[k].rmse);
        json_number(j, "psnr_db", d[k].psnr);
        json_string(j, "file", names[k]);
        json_end_object(j);
    }
    json_end_array(j);
    json_end_object(j);
}

/* What is rendered: a factors folder's or the job's factors, and the
 * original. */
typedef struct render_input {
    sb_source_t *src;
    sb_param_t *param; /* a folder's (owned) */
    sb_factors_t *f;
    sb_job_t *job; /* a SOURCE factored */
    const sb_param_t *pc;
    const sb_factors_t *fc;
    sb_form_t form;
} render_input_t;

static void input_free(render_input_t *in) {
    sb_job_destroy(in->job);
    sb_factors_destroy(in->f);
    sb_param_destroy(in->param);
    sb_source_destroy(in->src);
}

/* A folder written by `factor`: its factors, and the original from
 * --source, else the spec or description the factors record. */
static int open_dir(sb_context_t *ctx, render_opts_t *o, render_input_t *in) {
    sb_result_t r;
    if ((r = sb_factors_read_exr(ctx, o->input, &in->f)) != SB_OK ||
        (r = sb_factors_param(ctx, in->f, &in->param, &in->form)) != SB_OK)
        return cli_fail("render", ctx, r);
    in->pc = in->param;
    in->fc = in->f;
    const char *spec = o->source;
    if (!spec) spec = sb_factors_get_meta(in->f, "source_spec");
    if (!spec) spec = sb_factors_get_meta(in->f, "source");
    if (!spec) {
        cli_error("render", "%s records no source; name the original with --source", o->input);
        return EXIT_IO;
    }
    if ((r = sb_job_source_open(ctx, spec, &o->job.measured, &in->src)) != SB_OK) {
        if (o->source) return cli_fail("render", ctx, r);
        cli_error("render", "%s: cannot open its recorded source '%s' (%s); name it with --source", o->input, spec,
                  sb_context_last_error(ctx));
        return cli_exit_code(r);
    }
    size_t J = sb_factors_terms(in->f);
    if (o->nterms == 0)
        for (size_t k = 1; k <= J && k <= MAX_TERMS_LIST; k++)
            o->terms[o->nterms++] = k;
    for (size_t k = 0; k < o->nterms; k++)
        if (o->terms[k] > J) {
            cli_error("render", "--terms %zu: %s holds %zu terms", o->terms[k], o->input, J);
            return EXIT_USAGE;
        }
    return EXIT_OK;
}

/* A SOURCE: factored as `sepbrdf factor` does, with J the largest asked. */
static int factor_input(sb_context_t *ctx, render_opts_t *o, render_input_t *in) {
    if (o->nterms == 0) {
        static const size_t def[3] = {1, 2, 4};
        memcpy(o->terms, def, sizeof def);
        o->nterms = 3;
    }
    size_t J = 0;
    for (size_t k = 0; k < o->nterms; k++)
        if (o->terms[k] > J) J = o->terms[k];
    sb_result_t r = sb_job_source_open(ctx, o->input, &o->job.measured, &in->src);
    if (r != SB_OK) return cli_fail("render", ctx, r);
    o->job.source = o->input;
    o->job.terms = J;
    r = sb_job_run_source(ctx, in->src, &o->job, &in->job);
    cli_progress_done();
    if (r != SB_OK) return cli_job_fail("render", ctx, r, J);
    for (size_t i = 0; i < sb_job_warning_count(in->job); i++)
        cli_error("render", "warning: %s", sb_job_warning(in->job, i));
    in->pc = sb_job_param(in->job);
    in->fc = sb_job_factors(in->job);
    in->form = sb_job_form(in->job);
    /* fewer terms than asked (the job's warning says why): the J beyond them render as its last */
    size_t have = sb_factors_terms(in->fc), n = 0;
    for (size_t k = 0; k < o->nterms; k++) {
        size_t t = o->terms[k] < have ? o->terms[k] : have, dup = 0;
        for (size_t i = 0; i < n; i++)
            dup |= o->terms[i] == t;
        if (!dup) o->terms[n++] = t;
    }
    o->nterms = n;
    return EXIT_OK;
}

/* The channels f holds, a bit each: some term with a nonzero g and h
 * texel (factor --channels writes the others as zero). */
static unsigned factors_channels(const sb_factors_t *f) {
    unsigned held = 0;
    size_t J = sb_factors_terms(f), C = sb_factors_channels(f), n[2];
    for (int s = 0; s < 2; s++) {
        size_t w, h;
        sb_factors_size(f, s, &w, &h);
        n[s] = w * h;
    }
    for (size_t c = 0; c < C && c < 3; c++)
        for (size_t j = 0; j < J && !(held >> c & 1); j++) {
            int nz[2] = {0, 0};
            for (int s = 0; s < 2; s++) {
                const double *t = sb_factors_tex_const(f, s, j, c);
                for (size_t i = 0; t && i < n[s] && !nz[s]; i++)
                    nz[s] = t[i] != 0;
            }
            if (nz[0] && nz[1]) held |= 1u << c;
        }
    return held;
}

/* The original's channels the factors do not hold, zeroed so that the
 * images and errors compare the channels factored (as report.json's
 * errors do); returns those that had a value. */
static unsigned drop_channels(sb_image_t *img, unsigned held) {
    unsigned dropped = 0;
    size_t n = img->width * img->height;
    for (int c = 0; c < 3; c++)
        for (size_t i = 0; !(held >> c & 1) && i < n; i++) {
            if (img->rgb[3 * i + c] != 0) dropped |= 1u << c;
            img->rgb[3 * i + c] = 0;
        }
    return dropped;
}

/* Render the original and each reconstruction into the set: PNGs and
 * render.json; d and names receive one entry per J. */
static sb_result_t render_set(sb_context_t *ctx, render_opts_t *o, const render_input_t *in, sb_outset_t *set,
                              sb_image_diff_t *d, char names[][32]) {
    sb_image_t orig = {0}, rec = {0};
    sb_result_t r = sb_render_source(ctx, &o->scene, in->src, &orig);
    unsigned held = factors_channels(in->fc);
    if (r == SB_OK && held) o->dropped = drop_channels(&orig, held);
    if (r == SB_OK && o->tm.exposure <= 0) { /* auto (0) or peak (-1) */
        double peak = sb_image_max(&orig), key = sb_image_log_average(&orig);
        o->exposure_rule = o->tm.exposure < 0 ? "peak" : "auto";
        if (o->tm.exposure < 0 || !(key > 0))
            o->tm.exposure = peak > 0 ? 1 / peak : 1;
        else
            o->tm.exposure = 0.18 / key;
    }
    if (r == SB_OK) r = write_png(ctx, set, "original.png", &orig, NULL, o);
    for (size_t k = 0; k < o->nterms && r == SB_OK; k++) {
        cli_progress("rendering", (double)(k + 1) / (double)(o->nterms + 1));
        sb_image_free(&rec);
        if ((r = sb_render_factors(ctx, &o->scene, in->fc, in->pc, in->form, o->terms[k], &rec)) != SB_OK ||
            (r = sb_image_compare(ctx, &orig, &rec, &o->tm, &d[k])) != SB_OK)
            break;
        snprintf(names[k], sizeof names[k], "render_J%02zu.png", o->terms[k]);
        r = write_png(ctx, set, names[k], &orig, &rec, o);
    }
    cli_progress_done();
    sb_image_free(&orig);
    sb_image_free(&rec);
    if (r != SB_OK) return r;
    char path[4200], tmp[4300];
    FILE *fp = cli_set_file(set, "render.json", path, sizeof path) ? NULL : cli_open_tmp(path, tmp, sizeof tmp);
    int e = fp ? 0 : errno;
    if (fp) {
        json_t j = {fp, 0, {0}};
        write_json(&j, o, in->src, in->pc, in->form, d, names);
        e = cli_commit(fp, tmp, path, 1);
    }
    if (e) return sb_error(ctx, SB_ERR_IO, "%s/render.json: cannot write: %s", o->out, sb_io_why(e));
    return SB_OK;
}

static void print_result(const render_opts_t *o, const render_input_t *in, const sb_image_diff_t *d) {
    printf("sepbrdf render: %s\n  %s, form %s, %zu x %zu pixels, %zu light%s, tonemap %s, exposure %.4g\n",
           sb_source_description(in->src), sb_param_spec(in->pc), sb_form_name(in->form), o->scene.size, o->scene.size,
           o->scene.light_count, o->scene.light_count == 1 ? "" : "s", sb_tonemap_name(o->tm.op), o->tm.exposure);
    if (o->exposure_rule)
        printf("  exposure %s: %s\n", o->exposure_rule,
               o->exposure_rule[0] == 'a'
                   ? "the original's log-average luminance to 0.18 (--exposure peak: 1 / brightest)"
                   : "1 / the original's brightest channel");
    if (o->dropped) {
        char names[8] = "";
        size_t n = 0;
        for (int c = 0; c < 3; c++)
            if (o->dropped >> c & 1) names[n++] = "RGB"[c];
        printf("  channels %s left out of the original: the factors hold none (factor --channels)\n", names);
    }
    printf("%4s  %12s  %12s  %10s  %9s\n", "J", "rmse_linear", "max_linear", "rmse", "psnr_dB");
    for (size_t k = 0; k < o->nterms; k++)
        printf("%4zu  %12.4e  %12.4e  %10.4e  %9.2f\n", o->terms[k], d[k].rmse_linear, d[k].max_linear, d[k].rmse,
               d[k].psnr);
    printf("wrote original.png, %zu strips (difference x%g) and render.json to %s/\n", o->nterms, o->diff_scale,
           o->out);
}

/* --scene lights=...: its lights replace the others (the spec was checked
 * when parsed). */
static void scene_lights(render_opts_t *o) {
    sb_scene_t *s = NULL;
    if (!o->job.scene || sb_scene_parse(NULL, o->job.scene, &s) != SB_OK) return;
    size_t n = sb_scene_lights(s, o->scene.lights, SB_RENDER_MAX_LIGHTS);
    if (n) o->scene.light_count = n;
    sb_scene_destroy(s);
}

/* Options checked against each other; the defaults filled in. */
static int settle(render_opts_t *o, int *from_dir) {
    sb_light_from_angles(o->elev, o->azim, 0, &o->scene.lights[0]);
    scene_lights(o);
    if (o->scene.size == 0) o->scene.size = 256;
    *from_dir = o->input && is_dir(o->input);
    if (*from_dir && o->factor_opt_name) {
        cli_error("render", "%s applies when factoring a SOURCE, not to the factors folder %s", o->factor_opt_name,
                  o->input);
        return EXIT_USAGE;
    }
    if (!*from_dir && o->source) {
        cli_error("render", "--source applies to a factors folder; give the SOURCE itself instead");
        return EXIT_USAGE;
    }
    if (!o->input) o->input = SB_JOB_DEFAULT_SOURCE;
    return cli_check_outdir("render", "--out", o->out);
}

int cmd_render(int argc, char **argv) {
    render_opts_t o;
    memset(&o, 0, sizeof o);
    o.out = DEFAULT_OUT;
    o.elev = 45;
    o.azim = 45;
    o.tm.exposure = 0; /* auto */
    o.diff_scale = 4;
    o.scene.light_count = 1; /* slot 0 is the --light-elev/--light-azim light, filled after parsing */
    int from_dir, rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    if ((rc = settle(&o, &from_dir)) != EXIT_OK) return rc;
    sb_context_t *ctx = NULL;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("render", "out of memory");
        return EXIT_IO;
    }
    /* Inputs first: everything is checked before the output folder is touched */
    render_input_t in = {0};
    rc = from_dir ? open_dir(ctx, &o, &in) : factor_input(ctx, &o, &in);
    sb_outset_t *set = NULL;
    if (rc == EXIT_OK) {
        sb_image_diff_t d[MAX_TERMS_LIST];
        char names[MAX_TERMS_LIST][32];
        cli_progress("rendering", 0);
        /* The images go into a staging folder published in one step (outset.h) */
        if ((set = cli_outset_begin(ctx, "render", o.out, &rc)) != NULL) {
            sb_result_t r = render_set(ctx, &o, &in, set, d, names);
            rc = r != SB_OK ? cli_fail("render", ctx, r) : cli_outset_end(ctx, "render", set, 1);
            if (r == SB_OK) set = NULL;
            if (rc == EXIT_OK && g_verbosity >= 1) print_result(&o, &in, d);
        }
    }
    cli_progress_done();
    cli_outset_end(ctx, "render", set, 0); /* a set not published: discarded */
    input_free(&in);
    sb_context_destroy(ctx);
    return rc;
}
