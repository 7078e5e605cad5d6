/* Parameterisations not available yet in this build. */
#include "param_impl.h"

sb_result_t sb_param_init_io_area(sb_context_t *ctx, sb_param_t *p) {
    (void)p;
    return sb_error(ctx, SB_ERR_UNSUPPORTED, "parameterisation io-area is not available yet");
}
sb_result_t sb_param_init_hd(sb_context_t *ctx, sb_param_t *p) {
    (void)p;
    return sb_error(ctx, SB_ERR_UNSUPPORTED, "parameterisation hd is not available yet");
}
sb_result_t sb_param_init_iso(sb_context_t *ctx, sb_param_t *p) {
    (void)p;
    return sb_error(ctx, SB_ERR_UNSUPPORTED, "parameterisation iso is not available yet");
}
