/* Shared by test_api.c and test_api_out.c: one context, and CHECK_CODE,
 * which compares a call's result code and shows the context's last message
 * when it differs. */
#ifndef SB_API_CHECK_H
#define SB_API_CHECK_H

#include "harness.h"
#include "sepbrdf/experimental/layout.h"
#include "sepbrdf/experimental/solver.h"
#include "sepbrdf/sepbrdf.h"
#include "util/shared.h" /* sizes, JSON: not exported, in the static archive */

#define BAD_ENUM 99
static const double wi_up[3] = {0, 0, 1}, wo_up[3] = {0.6, 0, 0.8};

static inline sb_context_t *ctx(void) {
    static sb_context_t *c;
    if (!c) sb_context_create(&c);
    return c;
}

#define CHECK_CODE(call, code)                                                                                         \
    do {                                                                                                               \
        sb_context_clear_error(ctx());                                                                                 \
        sb_result_t r_ = (call);                                                                                       \
        CHECKF(r_ == (code), "%s = %s, want %s (%s)", #call, sb_result_name(r_), sb_result_name(code),                 \
               sb_context_last_error(ctx()));                                                                          \
    } while (0)

#endif
