/* The factor job's output set: textures, the error of what was stored,
 * previews, sepbrdf.glsl and report.json (keys: docs/report.md). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "sepbrdf/glsl.h"
#include "sepbrdf/image.h"
#include "sepbrdf/sampler.h"
#include "util/internal.h"
#include "util/parallel.h"

/* rel_rms of the stored (FLOAT or HALF) textures against the matrix, for
 * every J' (sb_err_at layout); NULL when it cannot be computed (reported as
 * null), and for a streamed matrix, where it would cost one more pass over
 * the source per channel. */
static double *stored_errors(sb_context_t *ctx, sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    if (a->m.streamed) return NULL;
    size_t J = sb_factors_terms(a->f);
    const sb_factors_t *q = NULL;
    double *rel = malloc(sb_err_at(J, 0) * sizeof *rel), *mx = malloc(sb_err_at(J, 0) * sizeof *mx);
    const sb_param_t *w = a->weighted ? a->param : NULL;
    int ok = rel && mx && job_quantized(ctx, job, a->f, &q) == SB_OK;
    if (ok)
        ok = (a->m.mask ? sb_factors_errors_against(ctx, q, &a->m, w, rel, mx)
                        : sb_factors_errors_near(ctx, a->f, q, &a->m, w, rel)) == SB_OK;
    free(mx);
    if (!ok) {
        free(rel);
        return NULL;
    }
    return rel;
}

static sb_result_t write_report_file(sb_context_t *ctx, const sb_job_t *job, sb_outset_t *set) {
    char path[4200];
    snprintf(path, sizeof path, "%s/report.json", sb_outset_dir(set));
    FILE *fp = fopen(path, "wb");
    int ok = fp != NULL;
    if (fp) {
        sb_job_report(job, fp);
        ok = fflush(fp) == 0 && !ferror(fp);
        ok = fclose(fp) == 0 && ok;
    }
    if (!ok || sb_outset_add(set, "report.json") != SB_OK)
        return sb_error(ctx, SB_ERR_IO, "%s/report.json: cannot write: %s", sb_outset_target(set), sb_io_why(errno));
    return SB_OK;
}

/* Name every texture of the set (sb_factors_write_exr wrote them). */
static sb_result_t add_textures(sb_outset_t *set, size_t J) {
    sb_result_t r = SB_OK;
    for (size_t k = 0; k < 2 * J && r == SB_OK; k++) {
        char name[64];
        sb_exr_name((int)(k % 2), k / 2, name, sizeof name);
        r = sb_outset_add(set, name);
    }
    return r;
}

/* sampler.bin, its integrals in the units of the stored textures of the
 * side it samples (h for SB_CAP_COL_SAMPLE layouts, else g). */
static sb_result_t write_sampler(sb_context_t *ctx, const sb_job_t *job, sb_outset_t *set, const sb_sampler_t *s) {
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    sb_exr_opts_t eo = {job->o.half};
    double *gs = malloc(J * sizeof *gs);
    sb_result_t r = gs ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    for (size_t j = 0; j < J && r == SB_OK; j++)
        r = sb_exr_texture_scale(ctx, a->f, (sb_param_caps(a->param) & SB_CAP_COL_SAMPLE) ? SB_SIDE_H : SB_SIDE_G, j,
                                 &eo, &gs[j]);
    char path[4200];
    snprintf(path, sizeof path, "%s/sampler.bin", sb_outset_dir(set));
    if (r == SB_OK) r = sb_sampler_write(ctx, s, path, gs);
    if (r == SB_OK && sb_outset_add(set, "sampler.bin") != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    free(gs);
    return r;
}

/* The snippet in the other languages asked for (opts.shaders): the text of
 * sepbrdf.glsl translated, as sepbrdf.<ext>. */
static sb_result_t write_translations(sb_context_t *ctx, const sb_job_t *job, sb_outset_t *set, const double *scales) {
    const job_attempt_t *a = &job->best;
    unsigned mask = 1;
    sb_result_t r = sb_shader_lang_list(ctx, job->o.shaders, &mask);
    if (r != SB_OK || mask == 1) return r;
    char *head = sb_glsl_snippet(a->param, a->m.form, sb_factors_terms(a->f), scales);
    int want = job->wrote_sampler && sb_param_sample_glsl(a->param)[0]; /* a layout may have its sampler in C only */
    char *tail = want ? sb_glsl_sampler(a->param, sb_factors_channels(a->f)) : NULL;
    char *glsl = head && (tail || !want) ? malloc(strlen(head) + (tail ? strlen(tail) : 0) + 1) : NULL;
    if (glsl) sprintf(glsl, "%s%s", head, tail ? tail : "");
    free(head);
    free(tail);
    if (!glsl) return sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    for (size_t k = 1; k < sb_shader_lang_count() && r == SB_OK; k++) {
        if (!(mask & (1u << k))) continue;
        char *text = sb_shader_translate(glsl, sb_shader_lang_name(k)), name[64], path[4200];
        if (!text) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
        snprintf(name, sizeof name, "sepbrdf.%s", sb_shader_lang_ext(k));
        snprintf(path, sizeof path, "%s/%s", sb_outset_dir(set), name);
        size_t len = text ? strlen(text) : 0;
        const void *parts[1] = {text};
        int e = text ? sb_write_atomic(path, parts, &len, 1) : 0;
        if (e) r = sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, sb_io_why(e));
        if (r == SB_OK && sb_outset_add(set, name) != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
        free(text);
    }
    free(glsl);
    return r;
}

/* sepbrdf.glsl; for non-negative factors (SB_CAP_NONNEG) also sampler.bin
 * and the sampler block appended to the snippet (sampler.h, glsl.h), where
 * the layout has one in GLSL (a program's layout may have it in C only: a
 * warning). */
static sb_result_t write_shader(sb_context_t *ctx, sb_job_t *job, sb_outset_t *set, const double *scales) {
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    char path[4200];
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", sb_outset_dir(set));
    sb_sampler_t *s = NULL;
    sb_context_t *sc = NULL; /* the refusal's own message (a layout without one, every term 0) */
    sb_result_t r = job_nonneg_method(sb_factors_get_meta(a->f, "method"))
                        ? (sb_context_create(&sc), sb_sampler_create(sc, a->f, a->param, a->m.form, &s))
                        : SB_OK;
    if (r == SB_ERR_NOMEM || r == SB_ERR_OVERFLOW) {
        sb_context_destroy(sc);
        return sb_error(ctx, r, "sampler: out of memory");
    }
    if (r != SB_OK) job_warn(job, "no %s", sc ? sb_context_last_error(sc) : sb_result_message(r));
    sb_context_destroy(sc);
    if (s) {
        /* the share from the fit's error against the source (sampler_share.c) */
        r = sb_sampler_choose_share(ctx, s, job->src, 0, &job->share);
        if (r == SB_OK) r = write_sampler(ctx, job, set, s);
        int gl = sb_param_sample_glsl(a->param)[0] != 0;
        if (r == SB_OK && !gl)
            job_warn(job, "no GLSL sampler: %s has its sampler in C only (sb_sample, sampler.bin)",
                     sb_param_kind_name(sb_param_kind(a->param)));
        if (r == SB_OK)
            r = gl ? sb_glsl_write_sampled(ctx, path, a->param, a->m.form, J, scales, sb_factors_channels(a->f))
                   : sb_glsl_write(ctx, path, a->param, a->m.form, J, scales);
        sb_sampler_destroy(s);
        job->wrote_sampler = r == SB_OK;
    } else {
        r = sb_glsl_write(ctx, path, a->param, a->m.form, J, scales);
    }
    if (r == SB_OK && sb_outset_add(set, "sepbrdf.glsl") != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = write_translations(ctx, job, set, scales);
    return r;
}

static sb_result_t write_set(sb_context_t *ctx, sb_job_t *job, sb_outset_t *set);

/* vndf.exr: the tables of a layout built on the source's own (SB_CAP_TABLES),
 * which its snippet reads as sb_vndf and render reads back. */
static sb_result_t write_tables(sb_context_t *ctx, const sb_param_t *p, sb_outset_t *set) {
    if (!(sb_param_caps(p) & SB_CAP_TABLES)) return SB_OK;
    size_t w, h;
    float *rgb = NULL;
    sb_result_t r = sb_param_tables_texture(p, &w, &h, &rgb);
    if (r != SB_OK) return sb_error(ctx, r, "vndf.exr: %s", sb_result_message(r));
    char path[4200];
    snprintf(path, sizeof path, "%s/vndf.exr", sb_outset_dir(set));
    r = sb_exr_write_rgb(ctx, path, w, h, rgb);
    free(rgb);
    if (r == SB_OK && sb_outset_add(set, "vndf.exr") != SB_OK) r = sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    return r;
}

/* One OpenBLAS thread, as in the job (job.c): the stored textures' error
 * pass makes many small calls, and waking the workers for each took 2 s
 * of the 4.7 s of `factor --param io -r 256 -J 8`. */
sb_result_t sb_job_write_set(sb_context_t *ctx, sb_job_t *job, sb_outset_t *set) {
    if (!job || !set || !job->best.f) return sb_error(ctx, SB_ERR_ARG, "sb_job_write_set: no job or no set");
    int blas = sb_blas_threads_begin(), cap = sb_thread_cap(job_thread_cap(job));
    sb_result_t r = write_set(ctx, job, set);
    sb_thread_cap(cap);
    sb_blas_threads_end(blas);
    return r;
}

static sb_result_t write_set(sb_context_t *ctx, sb_job_t *job, sb_outset_t *set) {
    double t0 = job_now();
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    const char *dir = sb_outset_dir(set);
    sb_exr_opts_t eo = {job->o.half};
    sb_result_t r = sb_factors_write_exr(ctx, a->f, dir, &eo);
    if (r == SB_OK && (r = add_textures(set, J)) != SB_OK) r = sb_error(ctx, r, "out of memory");
    if (r == SB_OK) r = write_tables(ctx, a->param, set);
    if (r == SB_OK) r = job_budget_written(ctx, job, dir); /* what the files hold, read back */
    if (r != SB_OK) return r;
    free(job->rel_stored);
    job->rel_stored = stored_errors(ctx, job);
    if (job->o.previews && (r = sb_factors_write_previews(ctx, a->f, dir)) != SB_OK) return r;
    /* the snippet's sb_scale: what the shader multiplies the stored texels by (1 for FLOAT) */
    double *scales = malloc(J * sizeof *scales);
    r = scales ? SB_OK : sb_error(ctx, SB_ERR_NOMEM, "out of memory");
    if (r == SB_OK) r = sb_exr_term_scales(ctx, a->f, &eo, scales);
    if (r == SB_OK) r = write_shader(ctx, job, set, scales);
    free(scales);
    if (r != SB_OK) return r;
    double t1 = job_now();
    job->t.write_s = t1 - t0;
    job->t.total_s = t1 - job->t_start;
    return write_report_file(ctx, job, set);
}

sb_result_t sb_job_write(sb_context_t *ctx, sb_job_t *job, const char *dir) {
    if (!job || !dir) return sb_error(ctx, SB_ERR_ARG, "sb_job_write: no job or no folder");
    sb_outset_opts_t so = {0};
    so.command = "factor";
    sb_outset_t *set = NULL;
    sb_result_t r = sb_outset_begin(ctx, dir, &so, &set);
    if (r == SB_OK) r = sb_job_write_set(ctx, job, set);
    if (r == SB_OK) r = sb_outset_commit(set);
    sb_outset_destroy(set);
    return r;
}
