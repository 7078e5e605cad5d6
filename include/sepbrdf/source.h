/* sepbrdf: the one interface of every BRDF source.
 *
 * Directions are unit vectors in the local shading frame: z is the surface
 * normal, x the tangent, y the bitangent.  Both point away from the surface:
 * wi towards the light (l), wo towards the viewer (v).  A source returns the
 * RGB value of f_r(wi, wo) in 1/sr.  Directions below the horizon (z <= 0)
 * give 0 for analytic sources. */
#ifndef SEPBRDF_SOURCE_H
#define SEPBRDF_SOURCE_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Properties a source declares; used to skip work (symmetric matrix build,
 * isotropic parameterisations) and to pick defaults. */
enum {
    SB_SOURCE_RECIPROCAL = 1u << 0, /* f(wi, wo) == f(wo, wi) */
    SB_SOURCE_ISOTROPIC = 1u << 1,  /* depends on phi_o - phi_i only */
    SB_SOURCE_MEASURED = 1u << 2,   /* a table: some pairs may be missing */
    SB_SOURCE_GRAY = 1u << 3,       /* R == G == B everywhere */
    SB_SOURCE_TABLES = 1u << 4,     /* carries tables a layout is built on (sb_source_layout_tables) */
    /* its data are f cos theta_i (an RGL file's values): f itself grows as
     * 1 / cos theta_i towards the horizon, so --param auto fits the form
     * cos only (a texture of f would have to hold the divergence) */
    SB_SOURCE_STORES_COS = 1u << 5,
    /* isotropic and even in the azimuth difference, f(theta_i, theta_o, d)
     * == f(theta_i, theta_o, -d) (mirror-symmetric about the plane of
     * incidence, as every analytic isotropic model): the io grid's table
     * is then evaluated for d <= 180 degrees and mirrored */
    SB_SOURCE_EVEN = 1u << 6
};

typedef struct sb_source_ops {
    /* Write f_r(wi, wo) to rgb[0..2].  Return 1 when the value is known
     * (analytic, measured or interpolated), 0 when the pair is missing
     * (rgb is then set to 0).  Must be thread-safe (called in parallel). */
    int (*eval)(const void *self, const double wi[3], const double wo[3], double rgb[3]);
    void (*destroy)(void *self); /* may be NULL */
} sb_source_ops_t;

typedef struct sb_source sb_source_t;

/* Wrap an implementation.  The source takes ownership of `self` (destroyed
 * through ops->destroy).  `description` is copied. */
SB_API sb_result_t sb_source_create(sb_context_t *ctx, const sb_source_ops_t *ops, void *self, unsigned flags,
                                    const char *description, sb_source_t **out);
SB_API void sb_source_destroy(sb_source_t *src); /* accepts NULL */

/* The tables a layout with SB_CAP_TABLES is built on (param.h: an
 * isotropic RGL file's VNDF warp, NDF and sigma, for the vndf layout),
 * owned by the source; NULL for a source without them (or NULL). */
SB_API const struct sb_layout_tables *sb_source_layout_tables(const sb_source_t *src);

/* A source that evaluates many pairs in one call (a function over arrays,
 * e.g. one written in Python with numpy): eval_many writes f_r of the n
 * pairs (wi[3k..3k+2], wo[3k..3k+2]) to rgb[3k..3k+2] and known[k] = 1, or
 * known[k] = 0 for a missing pair.  Called from several threads at once,
 * each with its own arrays; where the library samples a column of a matrix
 * or the estimator's pairs, it passes them in one call, elsewhere n = 1. */
typedef struct sb_source_batch_ops {
    void (*eval_many)(const void *self, size_t n, const double *wi, const double *wo, double *rgb,
                      unsigned char *known);
    void (*destroy)(void *self); /* may be NULL */
} sb_source_batch_ops_t;

/* Wrap a batched implementation as sb_source_create does. */
SB_API sb_result_t sb_source_create_batched(sb_context_t *ctx, const sb_source_batch_ops_t *ops, void *self,
                                            unsigned flags, const char *description, sb_source_t **out);

/* f_r of n pairs (arrays as eval_many's): one call of a batched source's
 * eval_many, else sb_source_eval pair by pair; rgb is 0 where known is 0.
 * Returns the number of known pairs (0 for NULL arguments). */
SB_API size_t sb_source_eval_many(const sb_source_t *src, size_t n, const double *wi, const double *wo, double *rgb,
                                  unsigned char *known);
/* Whether src has an eval_many (then callers gather pairs for it). */
SB_API int sb_source_batched(const sb_source_t *src);

/* f_r(wi, wo); returns 1 if known, 0 if missing (see sb_source_ops_t) or
 * an argument is NULL (rgb, when given, is then 0). */
SB_API int sb_source_eval(const sb_source_t *src, const double wi[3], const double wo[3], double rgb[3]);
SB_API unsigned sb_source_flags(const sb_source_t *src);
SB_API const char *sb_source_description(const sb_source_t *src);
SB_API void *sb_source_impl(const sb_source_t *src); /* the `self` passed at creation */

/* The measured samples behind a table, as measured, before any
 * interpolation: the number of sample slots (0 for analytic sources and
 * tables without samples), and slot k's directions and RGB f_r; returns 0
 * for a slot that holds no measurement (a missing MERL cell) or k out of
 * range, 1 otherwise.  Tables with samples: MERL (cells), scattered
 * tables (rows), RGL (colour nodes at their directions; a node whose light
 * falls below the horizon holds none). */
SB_API size_t sb_source_sample_count(const sb_source_t *src);
SB_API int sb_source_sample(const sb_source_t *src, size_t k, double wi[3], double wo[3], double f[3]);

/* Open a source from a user string: a model spec "MODEL[:key=value,...]"
 * (see models.h) or, when the string names an existing file, a measured
 * table (format by extension and content, see measured.h). */
SB_API sb_result_t sb_source_open(sb_context_t *ctx, const char *spec, sb_source_t **out);

#ifdef __cplusplus
}
#endif
#endif
