/* The registry of layouts (param.h, experimental/layout.h): the table of
 * the built-in ones, kinds numbered by name, registration from programs,
 * and the shape a layout's init sets. */
#include <assert.h>
#include <ctype.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "param/param_impl.h"
#include "sepbrdf/source.h"
#include "util/internal.h"

/* The built-in layouts, one row each: adding one is its file and its row
 * here.  The order of the rows is the order of help texts and of auto's
 * candidates; kinds are numbered by name at start-up (registry_build). */
#define SB_BUILTIN_LAYOUTS(X)                                                                                          \
    X(sb_param_desc_io)                                                                                                \
    X(sb_param_desc_io_area)                                                                                           \
    X(sb_param_desc_hd)                                                                                                \
    X(sb_param_desc_iso)                                                                                               \
    X(sb_param_desc_vh)                                                                                                \
    X(sb_param_desc_vndf)                                                                                              \
    X(sb_param_desc_rv)

#define SB_LAYOUT_EXTERN(id) extern const sb_param_desc_t id;
#define SB_LAYOUT_ROW(id) &id,
SB_BUILTIN_LAYOUTS(SB_LAYOUT_EXTERN)
static const sb_param_desc_t *const builtin[] = {SB_BUILTIN_LAYOUTS(SB_LAYOUT_ROW)};
#define NBUILTIN (sizeof builtin / sizeof builtin[0])

/* The kinds param.h numbers for programs written before kinds were
 * chosen by name: these names keep these numbers.  Frozen: a new layout
 * gets the next free number, never a row here. */
static const char *const numbered[] = {
    [SB_PARAM_IO] = "io",   [SB_PARAM_IO_AREA] = "io-area", [SB_PARAM_HD] = "hd",
    [SB_PARAM_ISO] = "iso", [SB_PARAM_VH] = "vh",
};
#define NNUMBERED (sizeof numbered / sizeof numbered[0])

/* The process's registry: kind k is registry[k], k < nkinds.  Rows are
 * written before nkinds counts them (release), so readers need no lock;
 * registrations take reg_mu. */
static const sb_param_desc_t *registry[SB_LAYOUTS_MAX];
static atomic_size_t nkinds;
static pthread_once_t reg_once = PTHREAD_ONCE_INIT;
static pthread_mutex_t reg_mu = PTHREAD_MUTEX_INITIALIZER;

/* The numbered kinds at their numbers, the other built-ins after them in
 * the order of their rows. */
static void registry_build(void) {
    size_t n = NNUMBERED;
    for (size_t i = 0; i < NBUILTIN; i++) {
        size_t at = n;
        for (size_t k = 0; k < NNUMBERED; k++)
            if (strcmp(numbered[k], builtin[i]->name) == 0) at = k;
        registry[at] = builtin[i];
        if (at == n) n++;
    }
    for (size_t k = 0; k < NNUMBERED; k++)
        assert(registry[k] && "a numbered kind's layout is missing");
    atomic_store_explicit(&nkinds, n, memory_order_release);
}

const sb_param_desc_t *sb_param_desc_of(sb_param_kind_t kind) {
    pthread_once(&reg_once, registry_build);
    return (size_t)(unsigned)kind < atomic_load_explicit(&nkinds, memory_order_acquire) ? registry[kind] : NULL;
}

size_t sb_param_kind_count(void) {
    pthread_once(&reg_once, registry_build);
    return atomic_load_explicit(&nkinds, memory_order_acquire);
}

sb_result_t sb_param_kind_parse(const char *name, sb_param_kind_t *out) {
    if (!out) return SB_ERR_ARG;
    size_t n = sb_param_kind_count();
    for (size_t k = 0; k < n && name; k++)
        if (strcmp(name, registry[k]->name) == 0) {
            *out = (sb_param_kind_t)k;
            return SB_OK;
        }
    return SB_ERR_UNKNOWN;
}
const char *sb_param_kind_name(sb_param_kind_t kind) {
    return sb_param_desc_of(kind) ? sb_param_desc_of(kind)->name : "?";
}
const char *sb_param_kind_description(sb_param_kind_t kind) {
    return sb_param_desc_of(kind) ? sb_param_desc_of(kind)->description : "?";
}
unsigned sb_param_kind_caps(sb_param_kind_t kind) { return sb_param_desc_of(kind) ? sb_param_desc_of(kind)->caps : 0; }
unsigned sb_param_caps(const sb_param_t *p) { return p ? p->desc->caps : 0; }

int sb_param_kind_applies(sb_param_kind_t kind, unsigned source_flags) {
    if (!sb_param_desc_of(kind)) return 0;
    if ((sb_param_kind_caps(kind) & SB_CAP_TABLES) && !(source_flags & SB_SOURCE_TABLES)) return 0;
    return !(sb_param_kind_caps(kind) & SB_CAP_NEEDS_ISOTROPY) || (source_flags & SB_SOURCE_ISOTROPIC);
}

size_t sb_param_kind_list(char *buf, size_t size, const char *sep) {
    size_t n = 0, count = sb_param_kind_count();
    if (!buf) size = 0;
    if (size) buf[0] = 0;
    for (size_t k = 0; k < count; k++) {
        const char *parts[2] = {k && sep ? sep : "", registry[k]->name};
        for (int i = 0; i < 2; i++) {
            if (n + 1 < size) snprintf(buf + n, size - n, "%s", parts[i]);
            n += strlen(parts[i]);
        }
    }
    return n;
}

/* What a registered descriptor must hold (sb_param_register). */
static const char *desc_problem(const sb_layout_desc_t *d) {
    if (!d->name || !d->name[0] || strcmp(d->name, "auto") == 0) return "no name, or the name auto";
    for (const char *c = d->name; *c; c++)
        if (!isalnum((unsigned char)*c) && *c != '-' && *c != '_') return "a name of letters, digits, - and _ only";
    if (!d->vt || !d->vt->cell_dirs || !d->vt->row_measure || !d->vt->col_measure || !d->vt->coords || !d->vt->glsl)
        return "a vt with every function and the GLSL";
    if (!(d->row_sample || d->col_sample) != !d->sample_glsl)
        return "sample_glsl with row_sample or col_sample, and not without";
    if (!d->row_cell != !d->row_edge || (d->row_cell && !d->row_sample))
        return "row_cell and row_edge both or neither, and row_sample with them";
    int cols = (d->caps & SB_CAP_COL_SAMPLE) != 0;
    if (!d->col_sample != !cols || !d->col_density != !cols || (cols && d->row_sample) || (d->col_weight && !cols))
        return "col_sample, col_density and SB_CAP_COL_SAMPLE all or none, not with row_sample, col_weight only with "
               "them";
    return NULL;
}

sb_result_t sb_param_register(sb_context_t *ctx, const sb_layout_desc_t *desc, sb_param_kind_t *kind) {
    if (!desc) return sb_error(ctx, SB_ERR_ARG, "param: no layout to register");
    const char *need = desc_problem(desc);
    if (need) return sb_error(ctx, SB_ERR_ARG, "param: layout '%s' needs %s", desc->name ? desc->name : "", need);
    sb_param_kind_t k;
    sb_result_t r = SB_OK;
    pthread_mutex_lock(&reg_mu);
    size_t n = sb_param_kind_count();
    if (sb_param_kind_parse(desc->name, &k) == SB_OK)
        r = sb_error(ctx, SB_ERR_RANGE, "param: a layout named '%s' is registered already", desc->name);
    else if (n == SB_LAYOUTS_MAX)
        r = sb_error(ctx, SB_ERR_RANGE, "param: %d layouts registered already, the most", SB_LAYOUTS_MAX);
    else {
        registry[n] = desc;
        atomic_store_explicit(&nkinds, n + 1, memory_order_release);
        if (kind) *kind = (sb_param_kind_t)n;
    }
    pthread_mutex_unlock(&reg_mu);
    return r;
}

const sb_param_opts_t *sb_param_options(const sb_param_t *p) { return p ? &p->opts : NULL; }

#define SHAPE_MAX ((size_t)1 << 26) /* rows or columns: beyond, no matrix fits */

sb_result_t sb_param_set_shape(sb_context_t *ctx, sb_param_t *p, const sb_layout_shape_t *s) {
    if (!p || !s || !s->spec || !p->in_init) return sb_error(ctx, SB_ERR_ARG, "param: a shape is set within init only");
    const char *name = p->desc->name;
    size_t n = strlen(name);
    if (strncmp(s->spec, name, n) != 0 || (s->spec[n] && s->spec[n] != ':') || strlen(s->spec) > 256)
        return sb_error(ctx, SB_ERR_ARG, "param: spec '%.40s' is not \"%s[:key=value,...]\"", s->spec, name);
    if (!s->g[0] || !s->g[1] || !s->h[0] || !s->h[1] || s->g[0] > SHAPE_MAX / s->g[1] || s->h[0] > SHAPE_MAX / s->h[1])
        return sb_error(ctx, SB_ERR_RANGE, "param: %s: textures of 1..2^26 texels", name);
    const int *wraps[2] = {s->wrap_g, s->wrap_h};
    for (int side = 0; side < 2; side++)
        for (int axis = 0; axis < 2; axis++) {
            if (wraps[side][axis] != SB_WRAP_CLAMP && wraps[side][axis] != SB_WRAP_REPEAT)
                return sb_error(ctx, SB_ERR_ARG, "param: %s: wrap %d is neither clamp nor repeat", name,
                                wraps[side][axis]);
            p->wrap[side][axis] = wraps[side][axis];
        }
    p->tex_w[SB_SIDE_G] = s->g[0], p->tex_h[SB_SIDE_G] = s->g[1];
    p->tex_w[SB_SIDE_H] = s->h[0], p->tex_h[SB_SIDE_H] = s->h[1];
    p->rows = s->g[0] * s->g[1];
    p->cols = s->h[0] * s->h[1];
    sb_param_spec_set(p, s->spec);
    return SB_OK;
}
