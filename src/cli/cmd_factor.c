/* sepbrdf factor: option parsing and printing around the library's factor
 * job (job.h), which chooses, factors and writes the output set. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "pipeline.h"
#ifdef SEPBRDF_MPI
#include "batch.h"
#endif

#define DEFAULT_OUT "sepbrdf-out"

static void help(void) {
    printf("usage: sepbrdf factor [SOURCE] [OPTIONS]\n"
           "\n"
           "Sample SOURCE on a hemisphere grid, factor it by a truncated SVD into J\n"
           "texture pairs g_j(wi), h_j(wo), and write into the output folder:\n"
           "  g_JJ.exr, h_JJ.exr   one EXR per texture and term (R, G, B float32)\n"
           "  report.json          errors per J, sigma_j, timings, settings\n"
           "  sepbrdf.glsl         GLSL snippet: vec3 sb_brdf(vec3 L, vec3 V)\n"
           "  sampler.bin          with --method nmf only (non-negative factors, every\n"
           "                       layout): importance sampling tables; the snippet\n"
           "                       then also has sb_sample(V, u, L, pdf) and\n"
           "                       sb_pdf(L, V);\n"
           "                       the table and report.json then also show the SVD's\n"
           "                       errors in the same layout beside (svd_headline,\n"
           "                       svd_rel_rms, nmf_over_svd): what positivity costs\n"
           "\n"
           "SOURCE  MODEL[:key=value,...] (see `sepbrdf list`) or a measured file.\n"
           "        default: " SB_JOB_DEFAULT_SOURCE "\n"
           "\n"
           "options:\n"
           "  -o, --out DIR        output folder, created if missing (default ./" DEFAULT_OUT ")\n");
    cli_table_help(cli_factor_options, CLI_FACTOR);
    printf(CLI_MEASURED_HELP CLI_VERBOSITY_HELP
           "\n"
           "`--param io --form f --unweighted --plain-terms` reproduces the lecture's\n"
           "method exactly (form f, unweighted, the truncated SVD's terms as they are).\n"
           "\n"
           "Texture layout: texel (x, y) of an R x R io texture is theta index x\n"
           "(s = theta / theta_max, clamped) and phi index y (t = phi / 2pi, repeated),\n"
           "i.e. direction k = R * i_phi + i_theta of the lecture's sequentialisation.\n"
           "\n"
           "The set (with sepbrdf-set-factor.txt, its list of files) is written beside the folder\n"
           "and swapped in whole when complete: the folder holds the previous set until\n"
           "then, whatever ends the run; files sepbrdf did not write stay.\n"
           "\n"
           "On a cluster: `mpirun -np N sepbrdf-mpi factor ... --method stream` (or srun;\n"
           "sepbrdf-mpi is built where MPI is found) shares the passes over a streamed\n"
           "matrix out to N ranks, one per node; rank 0 writes the folder.\n"
           "\n"
           "Candidates of --param auto lost to memory or a failure are warnings; when\n"
           "the one kept is then poor (headline above 50 %%), the set is written and\n"
           "the exit status is 2.\n"
           "\n" CLI_EXIT_HELP);
}

/* Parse argv into o; returns an exit code, or -1 to go on. */
static int parse(int argc, char **argv, sb_job_opts_t *o, const char **out) {
    cli_parser_t p = {.cmd = "factor",
                      .help = help,
                      .out_what = "folder",
                      .out = out,
                      .tables = {{cli_factor_options, CLI_FACTOR, o, NULL}},
                      .measured = &o->measured,
                      .what = "SOURCE",
                      .args = &o->source,
                      .max_args = 1};
    return cli_parse(argc, argv, &p);
}

static void print_candidates(const sb_job_t *job, const char *param) {
    const sb_job_candidate_t *c;
    fprintf(stderr, "--param %s screened (headline error, f cos theta_i, at J on an R-cell grid; time):\n",
            param && *param ? param : "auto");
    for (size_t i = 0; (c = sb_job_candidate(job, i)) != NULL; i++) {
        if (c->ok)
            fprintf(stderr, "  %-8s form %-4s %s %.4e  R = %-3zu %6.3f s  %-13s%s\n", sb_param_kind_name(c->kind),
                    sb_form_name(c->form), c->weighted ? "weighted" : "        ", c->error, c->res, c->time_s,
                    c->bands_ok == 1 ? "bands bounded" : (c->bands_ok == 0 ? "bands broken" : "bands n/a"),
                    c->kept      ? "  kept"
                    : c->dropped ? "  dropped"
                                 : "");
        else
            fprintf(stderr, "  %-8s form %-4s %s%s\n", sb_param_kind_name(c->kind), sb_form_name(c->form),
                    c->dropped ? "" : "failed: ", c->why); /* dropped unscreened: the why says so */
    }
}

/* -v: what the stages of the kept candidate did, on stderr. */
static void print_detail(const sb_job_t *job) {
    const sb_matrix_t *m = sb_job_matrix(job);
    sb_job_timings_t t;
    sb_plan_stats_t st;
    sb_job_timings(job, &t);
    sb_job_stats(job, &st);
    cli_info(2, "sampling %s on %s (%zu x %zu), form %s: %.3f s", sb_source_description(sb_job_source(job)),
             sb_param_spec(sb_job_param(job)), m->rows, m->cols, sb_form_name(m->form), t.sample_s);
    cli_info(2, "factoring: %zu terms%s%s, method %s: %.3f s; comparable error: %.3f s",
             sb_factors_terms(sb_job_factors(job)), sb_job_weighted(job) ? ", weighted" : "",
             st.masked ? (st.fit_converged ? ", masked fit" : ", masked fit (not converged)") : "",
             sb_factors_get_meta(sb_job_factors(job), "method"), t.factor_s, t.metric_s);
}

/* Whether the kept factors' method is non-negative (SB_CAP_NONNEG). */
static int nonneg_factors(const sb_job_t *job) {
    const char *name = sb_factors_get_meta(sb_job_factors(job), "method");
    for (size_t i = 0; name && i < sb_solver_count(); i++)
        if (strcmp(sb_solver_name(i), name) == 0) return (sb_solver_caps(i) & SB_CAP_NONNEG) != 0;
    return 0;
}

/* What the user must know about the kept fit, on stderr.  A non-negative
 * fit that ends at its sweep cap stopped by its stated rule (docs/guide.md:
 * Non-negative factors): a note, not a warning. */
static void print_warnings(const sb_job_t *job) {
    sb_plan_stats_t st;
    sb_job_stats(job, &st);
    if (!st.fit_converged && nonneg_factors(job))
        cli_info(1,
                 "factor: the non-negative fit stopped at its sweep cap (%d sweeps in all; report.json: fit.stopped)",
                 st.fit_iterations);
    else if (st.masked && !st.fit_converged && sb_job_fit_early_stop(job))
        cli_info(2,
                 "factor: a stage of the masked fit of the %zu terms written stopped at auto's early-stop cap (20 "
                 "sweeps a stage, %d in all; report.json: fit.early_stop): its stated rule, not a failure",
                 sb_factors_terms(sb_job_factors(job)), st.fit_iterations);
    else if (st.masked && !st.fit_converged)
        cli_error("factor",
                  "warning: the masked fit of the %zu terms written did not converge: a stage stopped at its sweep "
                  "cap (%d sweeps in all; report.json: fit.converged false); its errors are those of the factors "
                  "written",
                  sb_factors_terms(sb_job_factors(job)), st.fit_iterations);
    if (!sb_job_headline_non_increasing(job))
        cli_error("factor",
                  "warning: the headline error rises with J' (report.json: errors[].headline): the later terms fit "
                  "the sampled cells but not the pairs between them; fewer terms or a finer --res do better");
    const sb_estimate_t *e = sb_job_estimate(job);
    if (!e->converged)
        cli_info(1, "factor: the error estimate kept a standard error above 5 %% at %zu pairs", e->pairs);
}

static void print_table(const sb_job_t *job) {
    const sb_factors_t *f = sb_job_factors(job);
    const sb_matrix_t *m = sb_job_matrix(job);
    const sb_factor_errors_t *e = sb_factors_errors(f);
    static const char *const cn[3] = {"R", "G", "B"};
    const sb_estimate_t *est = sb_job_estimate(job);
    printf("%4s  %12s  %9s  %12s  %12s  %12s  %9s  %-10s %10s", "J", "headline", "+-", "comparable", "rel_rms",
           "max_abs", "negative", "worst_band", "error");
    for (int c = 0; c < 3; c++)
        if (sb_matrix_has(m, c)) printf("  %10s_%s", "rel_rms", cn[c]);
    int beside = !isnan(sb_job_svd_headline(job, 1)); /* --method nmf: the SVD's errors beside */
    if (beside) printf("  %12s  %11s  %12s", "svd_headline", "svd_rel_rms", "nmf_over_svd");
    printf("\n");
    for (size_t k = 0; k < sb_factors_terms(f); k++) {
        double se = k < est->terms ? est->se[k][SB_EST_FCOS][SB_CH_ALL] : NAN;
        printf("%4zu  %12.4e  %9.2e  %12.4e  %12.4e  %12.4e  %8.2f%%", k + 1, sb_job_headline(job, k + 1), se,
               sb_job_comparable(job, k + 1), e->rel_rms[sb_err_at(k, SB_CH_ALL)], e->max_abs[sb_err_at(k, SB_CH_ALL)],
               100 * sb_job_negative(job, k + 1));
        int wb = sb_estimate_worst_band(est, k + 1); /* report.json: errors[].band_rel */
        printf("  %-10s %10.3e", wb < 0 ? "-" : sb_band_name(wb), wb < 0 ? NAN : est->band[k][wb][SB_CH_ALL]);
        for (int c = 0; c < 3; c++)
            if (sb_matrix_has(m, c)) printf("  %12.4e", e->rel_rms[sb_err_at(k, (size_t)c)]);
        double ratio = sb_job_headline(job, k + 1) / sb_job_svd_headline(job, k + 1); /* report.json: null if 0/0 */
        if (beside && isfinite(ratio))
            printf("  %12.4e  %11.4e  %12.3f", sb_job_svd_headline(job, k + 1), sb_job_svd_rel_rms(job, k + 1), ratio);
        else if (beside)
            printf("  %12.4e  %11.4e  %12s", sb_job_svd_headline(job, k + 1), sb_job_svd_rel_rms(job, k + 1), "-");
        printf("\n");
    }
}

/* With --scene: the headline over the scene's pairs and over the whole
 * domain at J, with their standard errors. */
static void print_scene(const sb_job_t *job) {
    const sb_estimate_t *s = sb_job_estimate(job), *d = sb_job_domain_estimate(job);
    size_t J = sb_factors_terms(sb_job_factors(job));
    if (!d || J == 0 || J > s->terms || J > d->terms) return;
    printf("scene %s: headline at J = %zu over its pairs %.4e +- %.2e, over the whole domain %.4e +- %.2e\n",
           sb_scene_spec(sb_job_scene(job)), J, s->rel[J - 1][SB_EST_FCOS][SB_CH_ALL],
           s->se[J - 1][SB_EST_FCOS][SB_CH_ALL], d->rel[J - 1][SB_EST_FCOS][SB_CH_ALL],
           d->se[J - 1][SB_EST_FCOS][SB_CH_ALL]);
}

/* A scattered table: the error at the measurements each refit left out
 * (what most random splits see), every J'. */
static void print_cv(const sb_job_t *job) {
    size_t J = sb_factors_terms(sb_job_factors(job)), held = 0;
    double se;
    if (isnan(sb_job_cv(job, 1, &se, &held))) return;
    printf("held-out measurements (%zu, each predicted by a refit without its fold; what most random "
           "splits see), f cos theta_i:",
           held);
    for (size_t k = 1; k <= J; k++) {
        double v = sb_job_cv(job, k, &se, NULL);
        printf("%s J %zu %.4e +- %.1e", k > 1 ? "," : "", k, v, se);
    }
    printf("\n");
}

/* With --budget: what the search chose, and the bytes written. */
static void print_budget(const sb_job_t *job) {
    sb_job_budget_t b;
    if (!sb_job_budget(job, &b)) return;
    const sb_job_budget_try_t *c = &b.chosen;
    printf("budget %zu bytes: chose %s, form %s, %s warp, R = %zu (g %zux%zu, h %zux%zu texels), J = %zu, %s;\n"
           "  screened headline %.4e (%zu fits, %.3f s); its textures take %zu bytes as FLOAT, %zu as HALF;\n"
           "  the files written hold %zu bytes of texels (read back; %zu bytes on disk with headers)\n",
           b.budget, sb_param_kind_name(c->kind), sb_form_name(c->form), c->adaptive ? "adaptive" : "the layout's",
           c->res, c->g[0], c->g[1], c->h[0], c->h[1], c->terms, c->half ? "HALF" : "FLOAT", c->headline, b.fits,
           b.search_s, b.bytes_float, b.bytes_half, b.bytes_written, b.file_bytes);
}

/* The snippet files written: sepbrdf.glsl, then one per language of
 * --shader (sepbrdf.hlsl, ...). */
static void snippet_names(const char *shaders, char *buf, size_t size) {
    unsigned mask = 1;
    sb_shader_lang_list(NULL, shaders, &mask); /* parsed before the run: valid */
    buf[0] = 0;
    for (size_t k = 0; k < sb_shader_lang_count(); k++) {
        size_t len = strlen(buf);
        if ((mask >> k) & 1) snprintf(buf + len, size - len, "%ssepbrdf.%s", len ? ", " : "", sb_shader_lang_ext(k));
    }
}

static void print_result(const sb_job_t *job, const char *out, const char *shaders, int sampler) {
    const sb_matrix_t *m = sb_job_matrix(job);
    const sb_factors_t *f = sb_job_factors(job);
    sb_job_timings_t t;
    sb_job_timings(job, &t);
    printf("sepbrdf factor: %s\n  %s, %zu x %zu matrix, form %s%s, %zu term%s, method %s\n",
           sb_source_description(sb_job_source(job)), sb_param_spec(sb_job_param(job)), m->rows, m->cols,
           sb_form_name(m->form),
           sb_job_scene(job) ? ", scene weighted" : (sb_job_weighted(job) ? ", solid-angle weighted" : ""),
           sb_factors_terms(f), sb_factors_terms(f) == 1 ? "" : "s", sb_factors_get_meta(f, "method"));
    double cap = sb_param_theta_max(sb_job_param(job)) * 180 / SB_PI;
    if (!sb_job_scene(job) && cap < 90 - 1e-9)
        printf("  errors measured within the cap: both directions within %g deg of the normal (the snippet returns "
               "0 beyond)\n",
               cap);
    print_table(job);
    print_scene(job);
    print_cv(job);
    char snippets[128];
    snippet_names(shaders, snippets, sizeof snippets);
    size_t J = sb_factors_terms(f);
    int tables = (sb_param_caps(sb_job_param(job)) & SB_CAP_TABLES) != 0; /* vndf.exr, the tables the snippet reads */
    printf("wrote %zu texture pair%s, %s%sreport.json and %s to %s/ (%.3f s)\n", J, J == 1 ? "" : "s",
           tables ? "vndf.exr, " : "", sampler ? "sampler.bin, " : "", snippets, out, t.total_s);
    print_budget(job);
}

/* Whether the kept result is poor (headline at J above POOR_HEADLINE) while
 * candidates were lost to memory or failures: said on stderr, and the exit
 * status is 2 (the set is written all the same). */
#define POOR_HEADLINE 0.5
static int poor_after_loss(const sb_job_t *job) {
    size_t lost = sb_job_lost_count(job), J = sb_factors_terms(sb_job_factors(job));
    double h = sb_job_headline(job, J);
    if (!lost || !(h > POOR_HEADLINE)) return 0;
    cli_error("factor",
              "the layout kept has a headline error of %.3g %% at J = %zu and %zu candidate%s of --param auto %s lost "
              "(warnings above): more memory (--memory-limit, ulimit -v) or a lower --res may do far better",
              100 * h, J, lost, lost == 1 ? "" : "s", lost == 1 ? "was" : "were");
    return 1;
}

int cmd_factor(int argc, char **argv) {
    sb_job_opts_t o = {0};
    const char *out = DEFAULT_OUT;
    int rc = parse(argc, argv, &o, &out);
    if (rc >= 0) return rc;
    if ((rc = cli_check_outdir("factor", "--out", out)) != EXIT_OK) return rc;
    sb_context_t *ctx = NULL;
    sb_job_t *job = NULL;
    int rank = 0, size = 0, failed = 0, sampler = 0; /* sepbrdf-mpi: this rank, the ranks (0: MPI not started) */
    if (sb_context_create(&ctx) != SB_OK) {
        cli_error("factor", "out of memory");
        return EXIT_IO;
    }
#ifdef SEPBRDF_MPI
    if ((rc = factor_mpi_begin(ctx, &o, &rank, &size)) != EXIT_OK) goto out;
#endif
    o.progress = cli_job_progress;
    sb_result_t r = sb_job_run(ctx, &o, &job);
    cli_progress_done();
    failed = r != SB_OK;
    if (r == SB_OK && rank == 0) {               /* the other ranks shared the passes */
        size_t said = sb_job_warning_count(job); /* those the write adds (no sampler) follow it */
        for (size_t i = 0; i < said; i++)
            cli_error("factor", "warning: %s", sb_job_warning(job, i));
        /* auto's, or those of a layout named alone (its forms) */
        if ((sb_job_auto(job) || sb_job_candidate(job, 1)) && g_verbosity >= 1) print_candidates(job, o.param);
        print_detail(job);
        print_warnings(job);
        /* The whole set goes into a staging folder published in one step
         * (outset.h): the folder keeps its previous set until then. */
        sb_outset_t *set = cli_outset_begin(ctx, "factor", out, &rc);
        if (!set) goto out;
        r = sb_job_write_set(ctx, job, set);
        char staged[4200]; /* the staging folder holds this run's files alone */
        snprintf(staged, sizeof staged, "%s/sampler.bin", sb_outset_dir(set));
        sampler = r == SB_OK && access(staged, F_OK) == 0;
        for (size_t i = said; r == SB_OK && i < sb_job_warning_count(job); i++)
            cli_error("factor", "warning: %s", sb_job_warning(job, i));
        if (r != SB_OK) {
            cli_outset_end(ctx, "factor", set, 0);
        } else if ((rc = cli_outset_end(ctx, "factor", set, 1)) != EXIT_OK) {
            goto out;
        }
    }
    if (r == SB_OK && g_verbosity >= 1) print_result(job, out, o.shaders, sampler);
    if (r == SB_OK && rank == 0 && poor_after_loss(job)) {
        rc = EXIT_IO; /* written, but far from what the lost candidates might give */
        goto out;
    }
    if (r == SB_ERR_ARG && o.budget) /* the budget's own problems name it */
        cli_error("factor", "--budget %zu: %s", o.budget, sb_context_last_error(ctx));
    rc = r == SB_OK ? EXIT_OK : r == SB_ERR_ARG && o.budget ? EXIT_USAGE : cli_job_fail("factor", ctx, r, o.terms);
out:
#ifdef SEPBRDF_MPI
    factor_mpi_end(size, failed, rc);
#else
    (void)size, (void)failed;
#endif
    sb_job_destroy(job);
    sb_context_destroy(ctx);
    return rc;
}
