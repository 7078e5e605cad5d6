/* Measured tables: not in this build yet. */
#include "internal.h"

sb_result_t sb_measured_open_hook(sb_context_t *ctx, const char *path, sb_source_t **out) {
    (void)out;
    return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s: measured tables are not supported yet", path);
}
