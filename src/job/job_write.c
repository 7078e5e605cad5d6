/* The factor job's output set: textures, the error of what was stored,
 * previews, sepbrdf.glsl and report.json (keys: README "report.json"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "job_impl.h"
#include "sepbrdf/exr.h"
#include "sepbrdf/glsl.h"
#include "sepbrdf/image.h"
#include "util/internal.h"

/* mkdir -p */
static int make_dirs(const char *path) {
    char buf[4096];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) return -1;
    memcpy(buf, path, n + 1);
    for (char *p = buf + 1; *p; p++) {
        if (*p != '/') continue;
        *p = 0;
        mkdir(buf, 0777);
        *p = '/';
    }
    struct stat st;
    if (mkdir(buf, 0777) != 0 && !(stat(buf, &st) == 0 && S_ISDIR(st.st_mode))) return -1;
    return 0;
}

/* Terms K >= J left in dir by an earlier run would be taken for part of
 * this set: remove them. */
static void remove_stale_terms(const char *dir, size_t J) {
    for (size_t k = J;; k++) {
        int gone = 1;
        for (int side = 0; side < 2; side++) {
            char name[64], path[4200];
            sb_exr_name(side, k, name, sizeof name);
            snprintf(path, sizeof path, "%s/%s", dir, name);
            if (remove(path) == 0) gone = 0;
        }
        if (gone) break;
    }
}

/* rel_rms of the stored (FLOAT or HALF) textures against the matrix, for
 * every J' (J * 4); NULL when it cannot be computed (reported as null). */
static double *stored_errors(sb_context_t *ctx, const sb_job_t *job) {
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    sb_exr_opts_t eo = {job->o.half};
    sb_factors_t *q = NULL;
    double *rel = malloc(J * 4 * sizeof *rel), *mx = malloc(J * 4 * sizeof *mx);
    const sb_param_t *w = a->weighted ? a->param : NULL;
    int ok = rel && mx && sb_factors_quantize(ctx, a->f, &eo, &q, NULL) == SB_OK;
    if (ok)
        ok = (a->m.mask ? sb_factors_errors_against(ctx, q, &a->m, w, rel, mx)
                        : sb_factors_errors_near(ctx, a->f, q, &a->m, w, rel)) == SB_OK;
    sb_factors_destroy(q);
    free(mx);
    if (!ok) {
        free(rel);
        return NULL;
    }
    return rel;
}

static sb_result_t write_report_file(sb_context_t *ctx, const sb_job_t *job, const char *dir) {
    char path[4200], tmp[4300];
    snprintf(path, sizeof path, "%s/report.json", dir);
    snprintf(tmp, sizeof tmp, "%s.tmp-%ld", path, (long)getpid());
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return sb_error(ctx, SB_ERR_IO, "%s: cannot write", path);
    sb_job_report(job, fp);
    int ok = fflush(fp) == 0 && !ferror(fp);
    ok = fclose(fp) == 0 && ok;
    if (!(ok && rename(tmp, path) == 0)) {
        remove(tmp);
        return sb_error(ctx, SB_ERR_IO, "%s: cannot write", path);
    }
    return SB_OK;
}

sb_result_t sb_job_write(sb_context_t *ctx, sb_job_t *job, const char *dir) {
    if (!job || !dir || !job->best.f) return sb_error(ctx, SB_ERR_ARG, "sb_job_write: no job or no folder");
    double t0 = job_now();
    const job_attempt_t *a = &job->best;
    size_t J = sb_factors_terms(a->f);
    if (make_dirs(dir) != 0) return sb_error(ctx, SB_ERR_IO, "%s: cannot create the output folder", dir);
    sb_exr_opts_t eo = {job->o.half};
    sb_result_t r = sb_factors_write_exr(ctx, a->f, dir, &eo);
    if (r != SB_OK) return r;
    remove_stale_terms(dir, J);
    free(job->rel_stored);
    job->rel_stored = stored_errors(ctx, job);
    if (job->o.previews && (r = sb_factors_write_previews(ctx, a->f, dir)) != SB_OK) return r;
    char path[4200];
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", dir);
    if ((r = sb_glsl_write(ctx, path, a->param, a->m.form, J, NULL)) != SB_OK) return r;
    double t1 = job_now();
    job->t.write_s = t1 - t0;
    job->t.total_s = t1 - job->t_start;
    return write_report_file(ctx, job, dir);
}
