/* Glue between the factor group's commands and the factor job. */
#include "pipeline.h"

#include <unistd.h>

void cli_job_progress(void *user, const char *label, double fraction) {
    (void)user;
    cli_progress(label, fraction);
}

void cli_job_message(char *buf, size_t size, const sb_context_t *ctx, sb_result_t r, size_t terms) {
    const char *detail = sb_context_last_error(ctx);
    if (!detail || !*detail) detail = sb_result_message(r);
    if (r != SB_ERR_RANGE)
        snprintf(buf, size, "%s", detail);
    else if (terms)
        snprintf(buf, size, "--terms %zu exceeds what the matrix allows: %s", terms, detail);
    else
        snprintf(buf, size, "--terms: %s", detail);
}

int cli_job_fail(const char *cmd, const sb_context_t *ctx, sb_result_t r, size_t terms) {
    char msg[1024];
    cli_job_message(msg, sizeof msg, ctx, r, terms);
    cli_error(cmd, "%s", msg);
    return cli_exit_code(r);
}

void pipe_guard_factor_outputs(const char *dir, size_t terms, int on) {
    static const char *const names[] = {"sepbrdf.glsl", "report.json"};
    char path[4200];
    if (!on)
        cli_unguard_exr();
    else
        cli_guard_exr(dir, terms, 1);
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        for (int tmp = 0; tmp < 2; tmp++) {
            /* the final file, and its temporary PATH.tmp-PID (glsl.h, job.h) */
            if (tmp)
                snprintf(path, sizeof path, "%s/%s.tmp-%ld", dir, names[i], (long)getpid());
            else
                snprintf(path, sizeof path, "%s/%s", dir, names[i]);
            if (on)
                cli_guard(path);
            else
                cli_unguard(path);
        }
    }
}
