/* Fuzz the measured-table readers through sb_source_open on a file whose
 * extension the first input byte picks: .binary (MERL), .brdf (Cornell),
 * .dat / .alta (ALTA), .csv, .bsdf (RGL); the rest of the input is the
 * file.  A refusal is an input code (I/O, format, unsupported
 * variant, memory).  A source that
 * opens is evaluated at a few pairs (grazing and below the horizon
 * included) and sampled on a tiny io grid, with the matrix builder's invariants:
 * finite cells, mask 0 and value 0 where the source has no finite value. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "sepbrdf/sepbrdf.h"

static const char *const exts[] = {".binary", ".brdf", ".dat", ".alta", ".csv", ".bsdf"};

static void check_source(sb_context_t *ctx, const sb_source_t *src) {
    static const double dirs[][3] = {
        {0, 0, 1}, {0.6, 0, 0.8}, {-0.48, 0.36, 0.8}, {0.999999, 0, 0.0014142}, {0, 0, -1}, {1, 0, 0},
    };
    size_t n = sizeof dirs / sizeof dirs[0];
    for (size_t a = 0; a < n; a++)
        for (size_t b = 0; b < n; b++) {
            double rgb[3];
            (void)sb_source_eval(src, dirs[a], dirs[b], rgb);
        }
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    po.res = 3;
    SB_FUZZ_CHECK(sb_param_create(ctx, SB_PARAM_IO, &po, &p) == SB_OK);
    sb_matrix_t m;
    sb_matrix_opts_t mo = {0};
    mo.threads = 1;
    if (sb_matrix_build(ctx, src, p, &mo, &m) == SB_OK) {
        for (size_t i = 0; i < m.rows * m.cols; i++)
            for (int c = 0; c < 3; c++) {
                SB_FUZZ_CHECK(isfinite(m.data[c][i]));
                if (m.mask && !m.mask[i]) SB_FUZZ_CHECK(m.data[c][i] == 0);
            }
        sb_matrix_free(&m);
    }
    sb_param_destroy(p);
}

SB_FUZZ_ENTRY(measured) {
    const char *dir = sb_fuzz_setup();
    if (size < 1) return 0;
    const char *ext = exts[data[0] % (sizeof exts / sizeof exts[0])];
    char name[64], path[8192];
    snprintf(name, sizeof name, "in%s", ext);
    if (sb_fuzz_write(dir, name, data + 1, size - 1)) return 0;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    sb_context_t *ctx;
    SB_FUZZ_CHECK(sb_context_create(&ctx) == SB_OK);
    sb_source_t *src = (sb_source_t *)1;
    sb_result_t r = sb_source_open(ctx, path, &src);
    /* a file's content is input: never an option code (exit 1 in the CLI) */
    SB_FUZZ_CHECK(r == SB_OK || r == SB_ERR_IO || r == SB_ERR_FORMAT || r == SB_ERR_UNSUPPORTED || r == SB_ERR_NOMEM);
    if (r == SB_OK) {
        SB_FUZZ_CHECK(src != NULL && src != (sb_source_t *)1);
        check_source(ctx, src);
        sb_source_destroy(src);
    } else {
        SB_FUZZ_CHECK(src == NULL && sb_context_last_error(ctx)[0] != 0);
    }
    remove(path);
    sb_context_destroy(ctx);
    return 0;
}
