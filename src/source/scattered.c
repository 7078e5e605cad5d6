/* Scattered samples -> values anywhere: the interpolated source behind the
 * Cornell, ALTA and CSV readers (gonio.c), and its cross-validation.
 *
 * Every sample is a pair (l, v) with an RGB value of f_r.  Samples live in
 * an embedding where Euclidean distance is a distance between
 * configurations and where the symmetries that hold are folded:
 *   isotropic (3D): x = (theta_a, theta_b, |dphi|), dphi = phi_o - phi_i
 *     wrapped into [-pi, pi]; isotropy leaves only dphi, and its mirror
 *     dphi -> -dphi is folded by |dphi|; when reciprocal the swap l <-> v is
 *     folded by sorting, theta_a = max(theta_i, theta_o), theta_b = min
 *     (otherwise theta_a = theta_i, theta_b = theta_o).  Both folds are
 *     reflections, so the folded distance is the smallest distance to any
 *     symmetric copy and nothing is lost by folding.
 *   anisotropic (4D): x = (theta_i cos phi_i, theta_i sin phi_i, theta_o cos
 *     phi_o, theta_o sin phi_o) (polar maps of both hemispheres); when
 *     reciprocal every sample is stored a second time as (v, l).
 * Why io angles and not half/difference angles: on a 5 deg simulated
 * gonioreflectometer grid of the gold microfacet BRDF the half/difference
 * embeddings tried, (theta_h, theta_d cos phi_d, theta_d sin phi_d) and
 * variants, reached 2-5 % relative error at R = 16 (the phi_d cone at
 * theta_h = 0 and the grazing Fresnel ridge), this one 0.8 %, as good as
 * trilinear interpolation on the grid itself (1.0 %).  The azimuth is not
 * shrunk towards the normal (where it stops mattering): doing so packs the
 * samples of one elevation pair so tightly that they crowd out the next
 * elevations from the k nearest.  The cost is that near the normal a table
 * must hold the azimuths queried to cover them.
 *
 * A k-d tree answers the k nearest samples within a support of twice the
 * radius; a query whose nearest sample is farther than the radius is
 * missing.  The value is a weighted least-squares fit (weights 1/d^2, a
 * small ridge) of a local quadratic (default) or linear polynomial in the
 * embedding, evaluated at the query and clamped to the range of the
 * neighbours' values, or inverse-distance weighting, or the nearest sample.
 * Read-only after building, so eval is thread-safe.
 *
 * Files: this one collects the samples and builds the source;
 * scattered_kd.c embeds and searches neighbours, scattered_fit.c fits and
 * evaluates, scattered_cv.c cross-validates the methods. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "source/scattered_impl.h"
#include "util/internal.h"

#define RADIUS_FACTOR 2.5
#define SUPPORT_FACTOR 2.0
/* The slots of a table's memo (2 MiB of tags, and 80 bytes an entry for
 * each value stored, up to 3/4 of the slots: 15 MiB; entries are taken in
 * order, so only the pages of those stored are touched, memo.c): a
 * default run evaluates the Cornell acrylic's table at 340 000 pairs,
 * 255 000 positions; the screening grids (41 000 positions) and the kept
 * layout's grid repeat a quarter of them (reciprocity and isotropy fold
 * distinct pairs onto one position), the drawn pairs next to none.  hd at
 * R = 32 on an isotropic table (1M cells, the acrylic cut to one theta_i)
 * asks 1.54 M values in a run without the refits, 70 % of them at
 * positions asked before once positions are rounded (scattered_fit.c,
 * POSITION_GRID): 2^16 slots found 13 % of them, 2^18 and 2^20 70 %.  Until issue 32's h32t round
 * 2^16 (2^17 cost the acrylic 1.01x the CPU of 2^16, in alternation). */
#define TABLE_MEMO_CAP ((size_t)1 << 18)

/* ---- samples ----------------------------------------------------------- */

sb_result_t sb_samples_push_(sb_context_t *ctx, const char *path, sb_samples_t *ss, const double wi[3],
                             const double wo[3], const double f[3], sb_measured_info_t *info) {
    if (ss->n == ss->cap) {
        size_t cap = ss->cap ? 2 * ss->cap : 1024, bytes;
        if (cap > SB_MAX_ROWS) cap = SB_MAX_ROWS;
        if (ss->n >= SB_MAX_ROWS) return sb_error(ctx, SB_ERR_OVERFLOW, "%s: more than %zu samples", path, SB_MAX_ROWS);
        if (sb_size_mul3(cap, SB_SAMPLE_DOUBLES, sizeof(double), &bytes) || bytes > sb_memory_limit())
            return sb_error(ctx, SB_ERR_OVERFLOW, "%s: %zu samples exceed the memory limit", path, cap);
        double *s = realloc(ss->s, bytes);
        if (!s) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory at sample %zu", path, ss->n);
        ss->s = s;
        ss->cap = cap;
    }
    double *p = ss->s + ss->n * SB_SAMPLE_DOUBLES;
    memcpy(p, wi, 3 * sizeof *p);
    memcpy(p + 3, wo, 3 * sizeof *p);
    for (int c = 0; c < 3; c++) {
        p[6 + c] = f[c];
        if (f[c] < info->value_min[c]) info->value_min[c] = f[c];
        if (f[c] > info->value_max[c]) info->value_max[c] = f[c];
        info->value_mean[c] += f[c]; /* divided by the count at the end */
    }
    double ti = acos(fmin(wi[2], 1)), to = acos(fmin(wo[2], 1));
    if (ti > info->theta_i_max) info->theta_i_max = ti;
    if (to > info->theta_o_max) info->theta_o_max = to;
    ss->n++;
    return SB_OK;
}

/* ---- the source ---------------------------------------------------------- */

static void table_destroy(void *self) {
    table_t *t = self;
    if (!t) return;
    free(t->pts);
    free(t->val);
    free(t->raw);
    free(t->lb);
    free(t->split);
    free(t->smp);
    sb_memo_destroy(t->memo);
    free(t);
}

static size_t table_sample_count(const void *self) { return ((const table_t *)self)->ns; }
static int table_sample(const void *self, size_t k, double wi[3], double wo[3], double f[3]) {
    const double *s = ((const table_t *)self)->smp + k * SB_SAMPLE_DOUBLES;
    memcpy(wi, s, 3 * sizeof *wi);
    memcpy(wo, s + 3, 3 * sizeof *wo);
    memcpy(f, s + 6, 3 * sizeof *f);
    return 1;
}

/* Sort key of an embedded sample: its position on a grid of SAME_POSITION. */
typedef struct key {
    long long q[MAX_DIM];
    size_t i; /* sample * copies + copy */
} pkey_t;

static int key_cmp(const void *a, const void *b) {
    const pkey_t *x = a, *y = b;
    for (int k = 0; k < MAX_DIM; k++)
        if (x->q[k] != y->q[k]) return x->q[k] < y->q[k] ? -1 : 1;
    return 0;
}

/* Embed every sample (copy 1 of a reciprocal anisotropic table is the
 * swapped pair) and sort by position on a grid of SAME_POSITION, so that
 * repeats (and symmetric copies that fold onto each other) become runs of
 * equal keys.  keys holds n = samples * copies. */
static void sort_keys(const table_t *t, const sb_samples_t *ss, size_t copies, pkey_t *keys, size_t n) {
    for (size_t i = 0; i < n; i++) {
        const double *s = ss->s + (i / copies) * SB_SAMPLE_DOUBLES;
        int swap = (int)(i % copies);
        double x[MAX_DIM] = {0};
        sb_scat_embed_(t->iso, t->recip, swap ? s + 3 : s, swap ? s : s + 3, x);
        for (int a = 0; a < MAX_DIM; a++)
            keys[i].q[a] = (long long)llround(x[a] / SAME_POSITION);
        keys[i].i = i;
    }
    qsort(keys, n, sizeof *keys, key_cmp);
}

/* One point per run of equal keys: the position of its first sample, the
 * mean value and the count (val: 4 a point); perm the identity. */
static void merge_runs(const table_t *t, const sb_samples_t *ss, size_t copies, const pkey_t *keys, size_t n,
                       double *pts, double *val, size_t *perm) {
    for (size_t i = 0, p = 0; i < n; p++) {
        size_t j = i + 1;
        while (j < n && key_cmp(&keys[i], &keys[j]) == 0)
            j++;
        double acc[3] = {0, 0, 0}, x[MAX_DIM] = {0};
        for (size_t k = i; k < j; k++)
            for (int c = 0; c < 3; c++)
                acc[c] += ss->s[(keys[k].i / copies) * SB_SAMPLE_DOUBLES + 6 + (size_t)c];
        const double *s0 = ss->s + (keys[i].i / copies) * SB_SAMPLE_DOUBLES;
        int swap = (int)(keys[i].i % copies);
        sb_scat_embed_(t->iso, t->recip, swap ? s0 + 3 : s0, swap ? s0 : s0 + 3, x);
        memcpy(pts + p * MAX_DIM, x, MAX_DIM * sizeof(double));
        for (int c = 0; c < 3; c++)
            val[4 * p + (size_t)c] = acc[c] / (double)(j - i);
        val[4 * p + 3] = (double)(j - i);
        perm[p] = p;
        i = j;
    }
}

/* The points of t (t->n, pts, val, split) from the samples: repeats
 * merged, stored in the order of the k-d tree. */
static sb_result_t table_points(sb_context_t *ctx, const char *path, const sb_samples_t *ss, table_t *t) {
    size_t copies = (!t->iso && t->recip) ? 2 : 1, n, m = 0;
    if (sb_size_mul(ss->n, copies, &n)) return sb_error(ctx, SB_ERR_OVERFLOW, "%s: sample count overflows", path);
    pkey_t *keys = sb_alloc(ctx, n, sizeof *keys, path);
    if (!keys) return SB_ERR_NOMEM;
    sort_keys(t, ss, copies, keys, n);
    for (size_t i = 0; i < n; i++)
        m += i == 0 || key_cmp(&keys[i - 1], &keys[i]) != 0;
    double *pts = sb_alloc(ctx, m, MAX_DIM * sizeof(double), path);
    double *val = sb_alloc(ctx, m, 4 * sizeof(double), path);
    size_t *perm = sb_alloc(ctx, m, sizeof *perm, path);
    t->pts = sb_alloc(ctx, m, MAX_DIM * sizeof(double), path);
    t->val = sb_alloc(ctx, m, 4 * sizeof(double), path);
    t->split = sb_calloc(ctx, m, 1, path);
    sb_result_t r = SB_ERR_NOMEM;
    if (pts && val && perm && t->pts && t->val && t->split) {
        merge_runs(t, ss, copies, keys, n, pts, val, perm);
        t->n = m;
        sb_kd_build_(perm, pts, t->split, 0, m);
        for (size_t i = 0; i < m; i++) {
            memcpy(t->pts + i * MAX_DIM, pts + perm[i] * MAX_DIM, MAX_DIM * sizeof(double));
            memcpy(t->val + 4 * i, val + 4 * perm[i], 4 * sizeof(double));
        }
        r = SB_OK;
    }
    free(keys);
    free(perm);
    free(pts);
    free(val);
    return r;
}

/* The radius from o (0: RADIUS_FACTOR times the median spacing, < 0: no
 * limit) into t->r2 and t->s2; the spacing into *spacing. */
static sb_result_t table_radius(sb_context_t *ctx, table_t *t, const sb_measured_opts_t *o, double *spacing,
                                double *radius) {
    *spacing = sb_table_spacing_(ctx, t);
    if (*spacing < 0) return SB_ERR_NOMEM;
    *radius = o->radius;
    if (*radius == 0) *radius = *spacing > 0 ? RADIUS_FACTOR * *spacing : INFINITY;
    if (*radius < 0) *radius = INFINITY;
    t->r2 = *radius * *radius;
    t->s2 = SUPPORT_FACTOR * SUPPORT_FACTOR * t->r2;
    return SB_OK;
}

/* The source over the finished t (owned by it from here on); the
 * interpolation fields of info. */
static sb_result_t table_source(sb_context_t *ctx, const char *path, table_t *t, double spacing, double radius,
                                sb_measured_info_t *info, sb_source_t **out) {
    info->spacing = spacing;
    info->radius = radius;
    info->neighbours = t->interp == SB_INTERP_NEAREST ? 1 : t->k;
    info->interp = t->interp;
    info->dims = (size_t)t->dim;
    info->flags = SB_SOURCE_MEASURED | (t->iso ? SB_SOURCE_ISOTROPIC : 0u) | (t->recip ? SB_SOURCE_RECIPROCAL : 0u) |
                  (info->channels == 1 ? SB_SOURCE_GRAY : 0u);
    char *desc = sb_format("%s:%s (%s, k=%zu, radius=%.3g deg)", info->format, path, sb_interp_name(t->interp),
                           info->neighbours, radius * 180 / SB_PI); /* paths of any length */
    sb_source_ops_t ops = {sb_table_eval_, table_destroy};
    t->memo = sb_memo_create(TABLE_MEMO_CAP); /* none: every value computed */
    sb_result_t r = desc ? sb_source_create(ctx, &ops, t, info->flags, desc, out) : SB_ERR_NOMEM;
    free(desc);
    if (r != SB_OK) {
        table_destroy(t);
        return r;
    }
    sb_source_set_samples_(*out, table_sample_count, table_sample);
    return SB_OK;
}

size_t sb_measured_fold(size_t i, size_t folds) {
    if (folds < 2) return 0;
    uint64_t z = (uint64_t)i + 0x9e3779b97f4a7c15ull; /* splitmix64 */
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return (size_t)((z ^ (z >> 31)) % folds);
}

/* A sample's place in the table's order: theta_i, phi_i, theta_o, phi_o
 * (phi in [0, 2 pi)), then the values; i its row. */
typedef struct row_key {
    double k[7];
    size_t i;
} row_key_t;

static int row_cmp(const void *a, const void *b) {
    const row_key_t *x = a, *y = b;
    for (int k = 0; k < 7; k++)
        if (x->k[k] != y->k[k]) return x->k[k] < y->k[k] ? -1 : 1;
    return 0;
}

/* On a grid of 1e-9 rad: a table written to text and read back (17
 * digits, degrees: the last bit moves) keeps its order. */
static void row_angles(const double w[3], double *theta, double *phi) {
    double t = acos(fmin(1, fmax(-1, w[2]))), p = atan2(w[1], w[0]);
    if (p < 0) p += 2 * SB_PI;
    *theta = (double)llround(t * 1e9);
    *phi = (double)(llround(p * 1e9) % llround(2 * SB_PI * 1e9));
}

/* The samples in one order whatever the file's: by angles as a
 * gonioreflectometer scans them (a table written in that order, as
 * `sample` writes one, keeps its order), then by value.  The folds, the
 * held-out samples of the interpolation's cross-validation and the lobe
 * fit's subsample are taken by index, so a table whose rows are shuffled
 * is the same table (the ALTA retro table shuffled read 0.118 against
 * 0.218, its interpolation chosen on other held-out rows).  Returns 0 when
 * out of memory (the order left as read). */
static int sort_rows(sb_samples_t *ss) {
    row_key_t *key = malloc(ss->n * sizeof *key);
    if (!key && ss->n) return 0;
    for (size_t i = 0; i < ss->n; i++) {
        const double *r = ss->s + i * SB_SAMPLE_DOUBLES;
        row_angles(r, &key[i].k[0], &key[i].k[1]);
        row_angles(r + 3, &key[i].k[2], &key[i].k[3]);
        for (int c = 0; c < 3; c++)
            key[i].k[4 + c] = r[6 + c] + 0.0;
        key[i].i = i;
    }
    qsort(key, ss->n, sizeof *key, row_cmp);
    for (size_t i = 0; i < ss->n; i++) { /* row key[i].i to place i, cycle by cycle, in place */
        if (key[i].i == SIZE_MAX || key[i].i == i) continue;
        double tmp[SB_SAMPLE_DOUBLES];
        memcpy(tmp, ss->s + i * SB_SAMPLE_DOUBLES, sizeof tmp);
        size_t at = i;
        while (key[at].i != i) {
            size_t from = key[at].i;
            memcpy(ss->s + at * SB_SAMPLE_DOUBLES, ss->s + from * SB_SAMPLE_DOUBLES, sizeof tmp);
            key[at].i = SIZE_MAX;
            at = from;
        }
        memcpy(ss->s + at * SB_SAMPLE_DOUBLES, tmp, sizeof tmp);
        key[at].i = SIZE_MAX;
    }
    free(key);
    return 1;
}

/* Cross-validation: drop the samples of fold o->cv_fold. */
static void drop_fold(sb_samples_t *ss, const sb_measured_opts_t *o) {
    if (o->cv_folds < 2) return;
    size_t kept = 0;
    for (size_t i = 0; i < ss->n; i++) {
        if (sb_measured_fold(i, o->cv_folds) == o->cv_fold) continue;
        if (kept != i)
            memmove(ss->s + kept * SB_SAMPLE_DOUBLES, ss->s + i * SB_SAMPLE_DOUBLES, SB_SAMPLE_DOUBLES * sizeof *ss->s);
        kept++;
    }
    ss->n = kept;
}

/* Build the source from the samples. */
sb_result_t sb_table_create_(sb_context_t *ctx, const char *path, sb_samples_t *ss, int iso, int recip,
                             const sb_measured_opts_t *o, sb_measured_info_t *info, sb_source_t **out) {
    sb_interp_t interp = o->interp == SB_INTERP_DEFAULT ? SB_INTERP_QUADRATIC : o->interp; /* until cv chooses */
    if (!sort_rows(ss)) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    drop_fold(ss, o);
    if (ss->n == 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: no usable samples (%zu rows: %zu NaN, %zu at or below the horizon)",
                        path, info->rows, info->nan_rows, info->horizon_rows);
    table_t *t = calloc(1, sizeof *t);
    if (!t) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    t->iso = iso;
    t->recip = recip;
    t->dim = iso ? 3 : 4;
    t->interp = interp;
    /* Default k: for the fits twice the quadratic's terms, plus a few: 24
     * (3D), 34 (4D); for idw a simplex, dim + 1 (more smears: on the 5 deg
     * round trip k = 4 gives 3.7 %, k = 8 8 %, k = 24 17 %). */
    size_t kfit = 2 * (size_t)(1 + t->dim + t->dim * (t->dim + 1) / 2) + 4;
    t->k = o->neighbours ? o->neighbours : interp == SB_INTERP_IDW ? (size_t)t->dim + 1 : kfit;
    double spacing = 0, radius = 0;
    sb_result_t r = table_points(ctx, path, ss, t);
    if (r == SB_OK) r = table_radius(ctx, t, o, &spacing, &radius);
    if (r != SB_OK) {
        table_destroy(t);
        return r;
    }
    t->smp = ss->s; /* the source keeps the samples (sort_rows' order) */
    t->ns = ss->n;
    ss->s = NULL;
    ss->n = ss->cap = 0;
    sb_table_cv_choose_(t, o, kfit, info);
    return table_source(ctx, path, t, spacing, radius, info, out);
}
