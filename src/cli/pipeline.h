/* sepbrdf CLI: glue between the commands of the factor group and the
 * library's factor job (job.h). */
#ifndef SEPBRDF_CLI_PIPELINE_H
#define SEPBRDF_CLI_PIPELINE_H

#include "cli.h"

/* sb_job_progress_fn drawing cli_progress (user unused). */
void cli_job_progress(void *user, const char *label, double fraction);

/* The message of a failed job into buf: the context's detail, naming
 * --terms (with J when terms > 0) when J was too large (SB_ERR_RANGE about
 * terms; other range errors name their own spec or key). */
void cli_job_message(char *buf, size_t size, const sb_context_t *ctx, sb_result_t r, size_t terms);
/* Print it ("sepbrdf CMD: ...") and return the exit code. */
int cli_job_fail(const char *cmd, const sb_context_t *ctx, sb_result_t r, size_t terms);

#endif
