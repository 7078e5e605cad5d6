/* Glue between the factor group's commands and the factor job. */
#include "pipeline.h"

void cli_job_progress(void *user, const char *label, double fraction) {
    (void)user;
    cli_progress(label, fraction);
}

void cli_job_message(char *buf, size_t size, const sb_context_t *ctx, sb_result_t r, size_t terms) {
    const char *detail = sb_context_last_error(ctx);
    if (!detail || !*detail) detail = sb_result_message(r);
    if (r == SB_ERR_OVERFLOW)
        snprintf(buf, size, "%s (lower --res)", detail); /* sizes beyond memory come from the resolution */
    else if (r != SB_ERR_RANGE)
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
