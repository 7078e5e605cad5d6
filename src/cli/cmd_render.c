/* sepbrdf render: the original BRDF and its reconstructions on a lit sphere,
 * PNG strips and errors per J. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "pipeline.h"

#define DEFAULT_SOURCE "microfacet:base=gold,roughness=0.5"
#define DEFAULT_OUT "sepbrdf-render"
#define MAX_TERMS_LIST 64

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
           "        factor` does (default: " DEFAULT_SOURCE ").\n"
           "DIR     a folder written by `sepbrdf factor`: its factors, parameterisation\n"
           "        and form; the original is --source, else SOURCE as factor was given\n"
           "        it (report.json), else the source the EXR files record.\n"
           "\n"
           "options:\n"
           "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n"
           "  -J, --terms LIST     numbers of terms to render, e.g. 1,2,4 (default 1,2,4;\n"
           "                       for DIR every J of the folder)\n"
           "  -r, --res R          as `sepbrdf factor`, for a SOURCE only, same defaults\n"
           "      --param P        (auto: every parameterisation that applies, forms f\n"
           "      --form F         and cos2, weighted, keeping the lowest comparable\n"
           "      --weighted       error at the largest J asked)\n"
           "      --zero-fill\n"
           "      --method M\n"
           "      --theta-max DEG\n"
           "      --source SPEC    the original to compare with (DIR only)\n"
           "  -s, --size N         image width and height in pixels, 8..4096 (default 256)\n"
           "      --light-elev DEG elevation of the light above the image plane, towards\n"
           "                       the viewer, 0..90 (default 45)\n"
           "      --light-azim DEG azimuth in the image plane from right towards up\n"
           "                       (default 45)\n"
           "      --light EL,AZ[,E]\n"
           "                       one more light (repeatable, up to %d in all), E its\n"
           "                       irradiance (default pi)\n"
           "      --exposure X|auto\n"
           "                       multiply radiance by X before tone mapping; auto\n"
           "                       (default): 1 / the original's brightest channel\n"
           "      --tonemap T      clamp (default) or reinhard (x / (1 + x))\n"
           "      --diff-scale N   magnification of the difference panel (default 4)\n" CLI_MEASURED_HELP
               CLI_VERBOSITY_HELP "\n"
           "Scene: unit sphere, orthographic camera looking down -z, tangent frame\n"
           "t = normalize(dP/dphi) of the sphere with its pole up (see docs/rendering.md);\n"
           "radiance = sum over lights of f_r(L, V) E cos(theta_L), E = pi by default.\n"
           "\n" CLI_EXIT_HELP,
           SB_RENDER_MAX_LIGHTS);
}

typedef struct render_opts {
    const char *input, *out, *source;
    size_t res, terms[MAX_TERMS_LIST], nterms;
    int param_auto; /* --param auto (default), as `sepbrdf factor` */
    sb_param_kind_t param;
    int form_set, weighted, zero_fill;
    sb_form_t form;
    sb_method_t method;
    double theta_max_deg;
    const char *factor_opt_name; /* a SOURCE-only option given, or NULL */
    sb_render_opts_t scene;
    double elev, azim;
    sb_tonemap_t tm;
    double diff_scale;
    sb_measured_opts_t mo; /* a measured table as SOURCE or --source */
} render_opts_t;

static int parse_terms(const char *v, render_opts_t *o) {
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

static int parse_light(const char *v, render_opts_t *o) {
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

static int parse(int argc, char **argv, render_opts_t *o) {
    static const char *const n_res[] = {"-r", "--res", NULL}, *const n_terms[] = {"-J", "--terms", NULL},
                             *const n_param[] = {"--param", NULL}, *const n_form[] = {"--form", NULL},
                             *const n_method[] = {"--method", NULL}, *const n_tmax[] = {"--theta-max", NULL},
                             *const n_src[] = {"--source", NULL}, *const n_size[] = {"-s", "--size", NULL},
                             *const n_el[] = {"--light-elev", NULL}, *const n_az[] = {"--light-azim", NULL},
                             *const n_light[] = {"--light", NULL}, *const n_exp[] = {"--exposure", NULL},
                             *const n_tm[] = {"--tonemap", NULL}, *const n_diff[] = {"--diff-scale", NULL},
                             *const n_w[] = {"--weighted", NULL}, *const n_zero[] = {"--zero-fill", NULL},
                             *const n_help[] = {"-h", "--help", NULL};
    cli_args_t a = {argc, 1, argv, "render"};
    for (; a.i < argc; a.i++) {
        const char *v = NULL, *arg = argv[a.i];
        int m;
        if ((m = cli_opt(&a, n_help, 0, &v))) {
            help();
            return 0;
        }
        if ((m = cli_out_opt(&a, "folder", &o->out))) {
            if (m < 0) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_terms, 1, &v))) {
            if (m < 0 || parse_terms(v, o)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_res, 1, &v))) {
            if (m < 0 || cli_parse_size("render", "--res", v, 2, 512, &o->res)) return EXIT_USAGE;
            o->factor_opt_name = "--res";
        } else if ((m = cli_opt(&a, n_param, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            o->param_auto = strcmp(v, "auto") == 0;
            if (!o->param_auto && sb_param_kind_parse(v, &o->param) != SB_OK) {
                cli_error("render", "--param '%s' unknown, need one of auto, %s", v, cli_param_names());
                return EXIT_USAGE;
            }
            o->factor_opt_name = "--param";
        } else if ((m = cli_opt(&a, n_form, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_form_parse(v, &o->form) != SB_OK) {
                cli_error("render", "--form '%s' unknown, need one of f, cos, cos2", v);
                return EXIT_USAGE;
            }
            o->form_set = 1;
            o->factor_opt_name = "--form";
        } else if (cli_opt(&a, n_w, 0, &v)) {
            o->weighted = 1;
            o->factor_opt_name = "--weighted";
        } else if (cli_opt(&a, n_zero, 0, &v)) {
            o->zero_fill = 1;
            o->factor_opt_name = "--zero-fill";
        } else if ((m = cli_opt(&a, n_method, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_method_parse(v, &o->method) != SB_OK) {
                cli_error("render", "--method '%s' unknown, need one of auto, full, topk, randomized", v);
                return EXIT_USAGE;
            }
            o->factor_opt_name = "--method";
        } else if ((m = cli_opt(&a, n_tmax, 1, &v))) {
            if (m < 0 || cli_parse_double("render", "--theta-max", v, 1, 90, &o->theta_max_deg)) return EXIT_USAGE;
            o->factor_opt_name = "--theta-max";
        } else if ((m = cli_opt(&a, n_src, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            o->source = v;
        } else if ((m = cli_opt(&a, n_size, 1, &v))) {
            if (m < 0 || cli_parse_size("render", "--size", v, 8, 4096, &o->scene.size)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_el, 1, &v))) {
            if (m < 0 || cli_parse_double("render", "--light-elev", v, 0, 90, &o->elev)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_az, 1, &v))) {
            if (m < 0 || cli_parse_double("render", "--light-azim", v, -360, 360, &o->azim)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_light, 1, &v))) {
            if (m < 0 || parse_light(v, o)) return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_exp, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (strcmp(v, "auto") == 0)
                o->tm.exposure = 0;
            else if (cli_parse_double("render", "--exposure", v, 1e-6, 1e6, &o->tm.exposure))
                return EXIT_USAGE;
        } else if ((m = cli_opt(&a, n_tm, 1, &v))) {
            if (m < 0) return EXIT_USAGE;
            if (sb_tonemap_parse(v, &o->tm.op) != SB_OK) {
                cli_error("render", "--tonemap '%s' unknown, need clamp or reinhard", v);
                return EXIT_USAGE;
            }
        } else if ((m = cli_opt(&a, n_diff, 1, &v))) {
            if (m < 0 || cli_parse_double("render", "--diff-scale", v, 1e-3, 1e6, &o->diff_scale)) return EXIT_USAGE;
        } else if ((m = cli_measured_opt(&a, &o->mo))) {
            if (m < 0) return EXIT_USAGE;
        } else if (cli_verbosity_opt(arg)) {
        } else if (arg[0] == '-' && arg[1]) {
            cli_error("render", "unknown option '%s' (see `sepbrdf render --help`)", arg);
            return EXIT_USAGE;
        } else if (!o->input) {
            o->input = arg;
        } else {
            cli_error("render", "more than one SOURCE or DIR given ('%s' and '%s')", o->input, arg);
            return EXIT_USAGE;
        }
    }
    return -1; /* go on */
}

static int is_dir(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Factor src as `sepbrdf factor` does (pipeline.h: the same candidates and
 * selection), with J = the largest of the list.  *best owns the kept attempt. */
static sb_result_t factor_source(sb_context_t *ctx, const render_opts_t *o, const sb_source_t *src, size_t J,
                                 attempt_t *best) {
    pipe_opts_t po = {o->res, J, 32, o->theta_max_deg, 0, o->method, 1, o->zero_fill, NULL, 0, 0, 0, 0, 0, NULL, 0, 0};
    pipe_cand_t cands[PIPE_MAX_CANDS];
    size_t ncand = pipe_candidates(src, &po, o->param_auto, o->param, o->form_set, o->form, o->weighted, cands);
    return pipe_select(ctx, "render", src, &po, cands, ncand, best);
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
    json_string(j, "sepbrdf_version", SB_VERSION_STRING);
    json_string(j, "command", "render");
    json_string(j, "source", sb_source_description(src));
    json_string(j, "param_spec", sb_param_spec(param));
    json_string(j, "form", sb_form_name(form));
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

int cmd_render(int argc, char **argv) {
    render_opts_t o;
    memset(&o, 0, sizeof o);
    o.out = DEFAULT_OUT;
    o.res = 32;
    o.param_auto = 1;
    o.param = SB_PARAM_IO;
    o.form = SB_FORM_F;
    o.theta_max_deg = 90;
    o.elev = 45;
    o.azim = 45;
    o.tm.exposure = 0; /* auto */
    o.diff_scale = 4;
    /* slot 0 is the --light-elev/--light-azim light, filled after parsing */
    o.scene.light_count = 1;
    int rc = parse(argc, argv, &o);
    if (rc >= 0) return rc;
    sb_light_from_angles(o.elev, o.azim, 0, &o.scene.lights[0]);
    if (o.scene.size == 0) o.scene.size = 256;
    int from_dir = o.input && is_dir(o.input);
    if (from_dir && o.factor_opt_name) {
        cli_error("render", "%s applies when factoring a SOURCE, not to the factors folder %s", o.factor_opt_name,
                  o.input);
        return EXIT_USAGE;
    }
    if (!from_dir && o.source) {
        cli_error("render", "--source applies to a factors folder; give the SOURCE itself instead");
        return EXIT_USAGE;
    }
    if (!o.input) o.input = DEFAULT_SOURCE;
    if ((rc = cli_check_outdir("render", "--out", o.out)) != EXIT_OK) return rc;

    sb_context_t *ctx = NULL;
    sb_outset_t *set = NULL;
    sb_source_t *src = NULL;
    sb_param_t *param = NULL;
    sb_factors_t *f = NULL;
    sb_image_t orig = {0}, rec = {0};
    sb_form_t form = o.form;
    sb_result_t r;
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("render", "out of memory");
        return EXIT_IO;
    }
    /* Inputs first: everything is checked before the output folder is touched */
    if (from_dir) {
        if ((r = sb_factors_read_exr(ctx, o.input, &f)) != SB_OK) goto fail;
        if ((r = sb_factors_param(ctx, f, &param, &form)) != SB_OK) goto fail;
        /* The original: --source, else SOURCE as `factor` was given it
         * (report.json), else the factors' source description (which a
         * model spec is, a measured table's is not) */
        char given[4096];
        const char *spec = o.source;
        if (!spec && cli_read_source_spec(o.input, given, sizeof given) == 0 &&
            pipe_source_open(ctx, given, &o.mo, &src) == SB_OK)
            spec = given;
        if (!spec) spec = sb_factors_get_meta(f, "source");
        if (!spec) {
            cli_error("render", "%s records no source; name the original with --source", o.input);
            rc = EXIT_IO;
            goto out;
        }
        if (!src && (r = pipe_source_open(ctx, spec, &o.mo, &src)) != SB_OK) {
            if (!o.source) {
                cli_error("render", "%s: cannot open its recorded source '%s' (%s); name it with --source", o.input,
                          spec, sb_context_last_error(ctx));
                rc = cli_exit_code(r);
                goto out;
            }
            goto fail;
        }
        size_t J = sb_factors_terms(f);
        if (o.nterms == 0)
            for (size_t k = 1; k <= J && k <= MAX_TERMS_LIST; k++)
                o.terms[o.nterms++] = k;
        for (size_t k = 0; k < o.nterms; k++)
            if (o.terms[k] > J) {
                cli_error("render", "--terms %zu: %s holds %zu terms", o.terms[k], o.input, J);
                rc = EXIT_USAGE;
                goto out;
            }
    } else {
        if (o.nterms == 0) {
            static const size_t def[3] = {1, 2, 4};
            memcpy(o.terms, def, sizeof def);
            o.nterms = 3;
        }
        size_t J = 0;
        for (size_t k = 0; k < o.nterms; k++)
            if (o.terms[k] > J) J = o.terms[k];
        if ((r = pipe_source_open(ctx, o.input, &o.mo, &src)) != SB_OK) goto fail;
        attempt_t best;
        if ((r = factor_source(ctx, &o, src, J, &best)) != SB_OK) goto fail;
        param = best.param; /* keep the parameterisation and factors */
        f = best.f;
        form = best.m.form;
        best.param = NULL;
        best.f = NULL;
        attempt_free(&best);
    }

    /* Render the original, then each reconstruction */
    cli_progress("rendering", 0);
    if ((r = sb_render_source(ctx, &o.scene, src, &orig)) != SB_OK) goto fail;
    if (o.tm.exposure == 0) {
        double peak = sb_image_max(&orig);
        o.tm.exposure = peak > 0 ? 1 / peak : 1;
    }
    sb_image_diff_t d[MAX_TERMS_LIST];
    char names[MAX_TERMS_LIST][32], path[4200];
    /* The images go into a staging folder published in one step (outset.h) */
    if (!(set = cli_outset_begin(ctx, "render", o.out, &rc))) goto out;
    if ((r = write_png(ctx, set, "original.png", &orig, NULL, &o)) != SB_OK) goto fail;
    for (size_t k = 0; k < o.nterms; k++) {
        cli_progress("rendering", (double)(k + 1) / (double)(o.nterms + 1));
        sb_image_free(&rec);
        if ((r = sb_render_factors(ctx, &o.scene, f, param, form, o.terms[k], &rec)) != SB_OK) goto fail;
        if ((r = sb_image_compare(ctx, &orig, &rec, &o.tm, &d[k])) != SB_OK) goto fail;
        snprintf(names[k], sizeof names[k], "render_J%02zu.png", o.terms[k]);
        if ((r = write_png(ctx, set, names[k], &orig, &rec, &o)) != SB_OK) goto fail;
    }
    cli_progress_done();
    char tmp[4300];
    FILE *fp = cli_set_file(set, "render.json", path, sizeof path) ? NULL : cli_open_tmp(path, tmp, sizeof tmp);
    int e = fp ? 0 : errno;
    if (fp) {
        json_t j = {fp, 0, {0}};
        write_json(&j, &o, src, param, form, d, names);
        e = cli_commit(fp, tmp, path, 1);
    }
    if (e) {
        cli_error("render", "%s/render.json: cannot write: %s", o.out, sb_io_why(e));
        rc = EXIT_IO;
        goto out;
    }
    if ((rc = cli_outset_end(ctx, "render", set, 1)) != EXIT_OK) {
        set = NULL;
        goto out;
    }
    set = NULL;
    if (g_verbosity >= 1) {
        printf("sepbrdf render: %s\n  %s, form %s, %zu x %zu pixels, %zu light%s, tonemap %s, exposure %.4g\n",
               sb_source_description(src), sb_param_spec(param), sb_form_name(form), o.scene.size, o.scene.size,
               o.scene.light_count, o.scene.light_count == 1 ? "" : "s", sb_tonemap_name(o.tm.op), o.tm.exposure);
        printf("%4s  %12s  %12s  %10s  %9s\n", "J", "rmse_linear", "max_linear", "rmse", "psnr_dB");
        for (size_t k = 0; k < o.nterms; k++)
            printf("%4zu  %12.4e  %12.4e  %10.4e  %9.2f\n", o.terms[k], d[k].rmse_linear, d[k].max_linear, d[k].rmse,
                   d[k].psnr);
        printf("wrote original.png, %zu strips (difference x%g) and render.json to %s/\n", o.nterms, o.diff_scale,
               o.out);
    }
    rc = EXIT_OK;
    goto out;
fail:
    cli_progress_done();
    rc = cli_fail("render", ctx, r);
out:
    cli_outset_end(ctx, "render", set, 0); /* a set not published: discarded */
    sb_image_free(&orig);
    sb_image_free(&rec);
    sb_factors_destroy(f);
    sb_param_destroy(param);
    sb_source_destroy(src);
    sb_context_destroy(ctx);
    return rc;
}
