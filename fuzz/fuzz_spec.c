/* Fuzz model specs: "MODEL[:key=value,...]" through sb_model_create and
 * sb_source_open, and the small name parsers.  Invariants: a failure
 * returns a documented code, no source and a message; a success gives a
 * source whose values above the horizon are known and finite. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "sepbrdf/sepbrdf.h"

static void check_source(const sb_source_t *src) {
    SB_FUZZ_CHECK(sb_source_description(src) != NULL);
    static const double dirs[][3] = {
        {0, 0, 1}, {0.6, 0, 0.8}, {-0.6, 0, 0.8}, {0, 0.999999, 0.0014142}, {0.70710678, 0.70710678, 1e-9}, {0, 0, -1},
    };
    size_t n = sizeof dirs / sizeof dirs[0];
    for (size_t a = 0; a < n; a++)
        for (size_t b = 0; b < n; b++) {
            double rgb[3] = {NAN, NAN, NAN};
            int known = sb_source_eval(src, dirs[a], dirs[b], rgb);
            if (dirs[a][2] > 0 && dirs[b][2] > 0) /* an analytic model knows every pair */
                SB_FUZZ_CHECK(known && isfinite(rgb[0]) && isfinite(rgb[1]) && isfinite(rgb[2]));
        }
}

SB_FUZZ_ENTRY(spec) {
    sb_fuzz_setup();
    if (size > 2048) return 0;
    char *s = malloc(size + 1);
    if (!s) return 0;
    memcpy(s, data, size);
    s[size] = 0;
    sb_context_t *ctx;
    SB_FUZZ_CHECK(sb_context_create(&ctx) == SB_OK);
    for (int open = 0; open < 2; open++) {
        /* sb_source_open takes an existing file as a measured table: only
         * strings that cannot name one outside the working folder */
        if (open && (strchr(s, '/') || strlen(s) != size)) break;
        sb_source_t *src = (sb_source_t *)1;
        sb_context_clear_error(ctx);
        sb_result_t r = open ? sb_source_open(ctx, s, &src) : sb_model_create(ctx, s, &src);
        SB_FUZZ_CHECK((unsigned)r < SB_RESULT_COUNT_);
        if (r == SB_OK) {
            SB_FUZZ_CHECK(src != NULL && src != (sb_source_t *)1);
            check_source(src);
            sb_source_destroy(src);
        } else {
            SB_FUZZ_CHECK(src == NULL);
            SB_FUZZ_CHECK(sb_context_last_error(ctx)[0] != 0);
        }
    }
    sb_form_t form;
    sb_method_t method;
    sb_param_kind_t kind;
    (void)sb_form_parse(s, &form);
    (void)sb_method_parse(s, &method);
    (void)sb_param_kind_parse(s, &kind);
    sb_context_destroy(ctx);
    free(s);
    return 0;
}
