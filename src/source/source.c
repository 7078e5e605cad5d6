/* The BRDF source interface: a vtable, flags and a description. */
#include "sepbrdf/source.h"

#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "sepbrdf/models.h"
#include "source/measured_impl.h"
#include "util/internal.h"

struct sb_source {
    sb_source_ops_t ops;
    void (*eval_many)(const void *self, size_t n, const double *wi, const double *wo, double *rgb,
                      unsigned char *known); /* batched sources (sb_source_create_batched), else NULL */
    void *self;
    unsigned flags;
    char *desc;
    sb_measured_info_t *minfo; /* a measured table's info (sb_measured_open), else NULL */
    size_t (*sample_count)(const void *self);
    int (*sample)(const void *self, size_t k, double wi[3], double wo[3], double f[3]);
    sb_layout_tables_t *tables; /* owned (sb_source_set_tables_), else NULL */
};

sb_result_t sb_source_create(sb_context_t *ctx, const sb_source_ops_t *ops, void *self, unsigned flags,
                             const char *description, sb_source_t **out) {
    if (!ops || !ops->eval || !out) return sb_error(ctx, SB_ERR_ARG, "source: missing eval function");
    sb_source_t *s = calloc(1, sizeof *s);
    char *d = sb_strdup(description ? description : "");
    if (!s || !d) {
        free(s);
        free(d);
        return sb_error(ctx, SB_ERR_NOMEM, "source: out of memory");
    }
    s->ops = *ops;
    s->self = self;
    s->flags = flags;
    s->desc = d;
    *out = s;
    return SB_OK;
}

/* The ops of a batched source: its pairs go to eval_one (sb_source_eval). */
static int no_eval(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    (void)self, (void)wi, (void)wo;
    rgb[0] = rgb[1] = rgb[2] = 0;
    return 0;
}

/* The one-pair eval of a batched source: eval_many with n = 1. */
static int eval_one(const sb_source_t *src, const double wi[3], const double wo[3], double rgb[3]) {
    unsigned char known = 0;
    src->eval_many(src->self, 1, wi, wo, rgb, &known);
    if (!known) rgb[0] = rgb[1] = rgb[2] = 0;
    return known != 0;
}

sb_result_t sb_source_create_batched(sb_context_t *ctx, const sb_source_batch_ops_t *ops, void *self, unsigned flags,
                                     const char *description, sb_source_t **out) {
    if (!ops || !ops->eval_many || !out) return sb_error(ctx, SB_ERR_ARG, "source: missing eval_many function");
    sb_source_ops_t one = {no_eval, ops->destroy}; /* sb_source_eval goes to eval_one */
    sb_result_t r = sb_source_create(ctx, &one, self, flags, description, out);
    if (r == SB_OK) (*out)->eval_many = ops->eval_many;
    return r;
}

int sb_source_batched(const sb_source_t *src) { return src && src->eval_many; }

size_t sb_source_eval_many(const sb_source_t *src, size_t n, const double *wi, const double *wo, double *rgb,
                           unsigned char *known) {
    if (!src || !wi || !wo || !rgb || !known) return 0;
    size_t count = 0;
    if (src->eval_many && n) src->eval_many(src->self, n, wi, wo, rgb, known);
    for (size_t k = 0; k < n; k++) {
        if (!src->eval_many)
            known[k] = (unsigned char)(src->ops.eval(src->self, wi + 3 * k, wo + 3 * k, rgb + 3 * k) != 0);
        if (!known[k]) rgb[3 * k] = rgb[3 * k + 1] = rgb[3 * k + 2] = 0;
        count += known[k] != 0;
    }
    return count;
}

void sb_source_destroy(sb_source_t *src) {
    if (!src) return;
    if (src->ops.destroy) src->ops.destroy(src->self);
    sb_layout_tables_destroy(src->tables);
    free(src->minfo);
    free(src->desc);
    free(src);
}

int sb_source_eval(const sb_source_t *src, const double wi[3], const double wo[3], double rgb[3]) {
    if (!src || !wi || !wo || !rgb) {
        if (rgb) rgb[0] = rgb[1] = rgb[2] = 0;
        return 0;
    }
    return src->eval_many ? eval_one(src, wi, wo, rgb) : src->ops.eval(src->self, wi, wo, rgb);
}
unsigned sb_source_flags(const sb_source_t *src) { return src ? src->flags : 0; }
const char *sb_source_description(const sb_source_t *src) { return src ? src->desc : ""; }
void *sb_source_impl(const sb_source_t *src) { return src ? src->self : NULL; }

size_t sb_source_sample_count(const sb_source_t *src) {
    return src && src->sample_count ? src->sample_count(src->self) : 0;
}
int sb_source_sample(const sb_source_t *src, size_t k, double wi[3], double wo[3], double f[3]) {
    if (k >= sb_source_sample_count(src)) return 0;
    return src->sample(src->self, k, wi, wo, f);
}

void sb_source_set_samples_(sb_source_t *src, size_t (*count)(const void *self),
                            int (*sample)(const void *self, size_t k, double wi[3], double wo[3], double f[3])) {
    src->sample_count = count;
    src->sample = sample;
}

void sb_source_set_tables_(sb_source_t *src, sb_layout_tables_t *tables) {
    sb_layout_tables_destroy(src->tables);
    src->tables = tables;
    if (tables)
        src->flags |= SB_SOURCE_TABLES;
    else
        src->flags &= ~(unsigned)SB_SOURCE_TABLES;
}

const sb_layout_tables_t *sb_source_layout_tables(const sb_source_t *src) { return src ? src->tables : NULL; }

int sb_source_set_measured_(sb_source_t *src, const sb_measured_info_t *info) {
    sb_measured_info_t *c = malloc(sizeof *c);
    if (!c) return -1;
    *c = *info;
    free(src->minfo);
    src->minfo = c;
    return 0;
}
const sb_measured_info_t *sb_measured_source_info(const sb_source_t *src) { return src ? src->minfo : NULL; }

/* A spec naming an existing regular file is a measured table; anything
 * else is a model spec.  A folder that is not also a model's name (a batch
 * writes folders named after models) is named as a folder: "unknown model"
 * misled where it was a factor set or a folder of tables. */
sb_result_t sb_source_open(sb_context_t *ctx, const char *spec, sb_source_t **out) {
    if (!spec || !out) return sb_error(ctx, SB_ERR_ARG, "source: no spec given");
    *out = NULL; /* also when a reader fails without touching it */
    struct stat st;
    int found = stat(spec, &st) == 0;
    if (found && S_ISREG(st.st_mode)) return sb_measured_open_hook(ctx, spec, out);
    sb_result_t r = sb_model_create(ctx, spec, out);
    if (r == SB_ERR_UNKNOWN && found && S_ISDIR(st.st_mode))
        return sb_error(ctx, SB_ERR_IO,
                        "%s: a folder, not a model or a measured file (a factor set is read by render, info and "
                        "view; the tables of a folder are factored by batch)",
                        spec);
    return r;
}
