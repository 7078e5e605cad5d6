/* Glue between the factor group's commands and the factor job. */
#include <string.h>

#include "pipeline.h"

void cli_job_progress(void *user, const char *label, double fraction) {
    (void)user;
    cli_progress(label, fraction);
}

void cli_job_message(char *buf, size_t size, const sb_context_t *ctx, sb_result_t r, size_t terms) {
    const char *detail = sb_context_last_error(ctx);
    if (!detail || !*detail) detail = sb_result_message(r);
    /* only a range error about J names --terms: a model key, a layout or a
     * scene out of range is named by its own message (issue 34) */
    int about_terms = r == SB_ERR_RANGE && strstr(detail, " terms ") != NULL;
    if (r == SB_ERR_OVERFLOW)
        snprintf(buf, size, "%s (lower --res)", detail); /* sizes beyond memory come from the resolution */
    else if (!about_terms && strncmp(detail, "scene: ", 7) == 0)
        snprintf(buf, size, "--%s", detail); /* the pairs file of --scene */
    else if (!about_terms)
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
