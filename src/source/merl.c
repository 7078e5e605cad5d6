/* MERL .binary tables: reader (nearest cell or trilinear), writer, and the
 * Rusinkiewicz half/difference angles.
 *
 * File: int32 dims (90, 90, 180) little-endian, then 3 planes (R, G, B) of
 * 90 * 90 * 180 float64 little-endian; cell (ih, id, ip) of a plane is at
 * ip + 180 (id + 90 ih).  f_r,c = stored * scale_c.  Bins:
 *     theta_h: u_h = 90 sqrt(theta_h / (pi/2))   (denser near the highlight)
 *     theta_d: u_d = 90 theta_d / (pi/2)
 *     phi_d:   u_p = 180 phi_d / pi, phi_d folded into [0, pi)
 * the cell index is floor(u) clamped; cell centres sit at floor(u) + 1/2.
 * In memory: 3 planes of doubles, already scaled, NaN for missing cells. */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "source/measured_impl.h"
#include "util/internal.h"
#include "util/parallel.h"

const double sb_merl_scale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};

/* Below this, sin(theta_h) or sin(theta_d) is treated as 0 and the azimuth
 * that becomes undefined there is set to 0 (the convention documented in
 * measured.h); it is far below the first theta_h bin (1.9e-4 rad). */
#define DEGENERATE_SIN 1e-12

/* ---- half / difference angles ------------------------------------------ */

/* h = normalize(wi + wo), theta_h, and d = wi (normalised) rotated by
 * -phi_h about z, then by -theta_h about y.  0 when wi = -wo. */
int sb_half_diff_vec_(const double wi[3], const double wo[3], double *theta_h, double d[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
    double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    double il = sqrt(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2]);
    if (!(hl > DEGENERATE_SIN * il)) return 0; /* wi = -wo: no half vector */
    for (int k = 0; k < 3; k++)
        h[k] /= hl;
    double th = acos(fmin(fmax(h[2], -1), 1));
    double hxy = hypot(h[0], h[1]);
    double cp = 1, sp = 0; /* phi_h = 0 when h is along the normal */
    if (hxy > DEGENERATE_SIN) {
        cp = h[0] / hxy;
        sp = h[1] / hxy;
    }
    double l[3];
    for (int k = 0; k < 3; k++)
        l[k] = wi[k] / il;
    double t0 = cp * l[0] + sp * l[1], t1 = -sp * l[0] + cp * l[1], t2 = l[2];
    double ct = cos(th), st = sin(th);
    d[0] = t0 * ct - t2 * st;
    d[1] = t1;
    d[2] = t0 * st + t2 * ct;
    *theta_h = th;
    return 1;
}

int sb_half_diff_angles(const double wi[3], const double wo[3], double *theta_h, double *theta_d, double *phi_d) {
    if (!wi || !wo || !theta_h || !theta_d || !phi_d) return 0;
    double d[3], th;
    if (!sb_half_diff_vec_(wi, wo, &th, d)) return 0;
    double pd = 0; /* phi_d = 0 when wi = wo */
    if (hypot(d[0], d[1]) > DEGENERATE_SIN) {
        pd = atan2(d[1], d[0]);
        if (pd < 0) pd += 2 * SB_PI;
        if (pd >= 2 * SB_PI) pd -= 2 * SB_PI;
    }
    *theta_h = th;
    *theta_d = acos(fmin(fmax(d[2], -1), 1));
    *phi_d = pd;
    return 1;
}

int sb_half_diff_dirs(double theta_h, double theta_d, double phi_d, double wi[3], double wo[3]) {
    if (!wi || !wo) return 0;
    double d[3];
    sb_dir_from_angles(theta_d, phi_d, d);
    double ct = cos(theta_h), st = sin(theta_h);
    /* rotate by +theta_h about y (phi_h = 0) */
    wi[0] = d[0] * ct + d[2] * st;
    wi[1] = d[1];
    wi[2] = -d[0] * st + d[2] * ct;
    double h[3] = {st, 0, ct}, lh = wi[0] * h[0] + wi[2] * h[2];
    for (int k = 0; k < 3; k++)
        wo[k] = 2 * lh * h[k] - wi[k];
    return wi[2] > 0 && wo[2] > 0;
}

/* Continuous index-space coordinates of a pair (cell k spans [k, k+1)). */
static int merl_coords(const double wi[3], const double wo[3], double u[3]) {
    if (wi[2] <= 0 || wo[2] <= 0) return 0;
    double th, td, pd;
    if (!sb_half_diff_angles(wi, wo, &th, &td, &pd)) return 0;
    if (pd >= SB_PI) pd -= SB_PI; /* reciprocity */
    u[0] = th > 0 ? SB_MERL_TH * sqrt(th / (SB_PI / 2)) : 0;
    u[1] = SB_MERL_TD * td / (SB_PI / 2);
    u[2] = SB_MERL_PD * pd / SB_PI;
    return 1;
}

static size_t clamp_index(double u, size_t n) {
    if (!(u > 0)) return 0;
    return u >= (double)(n - 1) ? n - 1 : (size_t)u;
}

static size_t cell_at(size_t ih, size_t id, size_t ip) { return ip + SB_MERL_PD * (id + SB_MERL_TD * ih); }

int sb_merl_index(const double wi[3], const double wo[3], size_t *index) {
    double u[3];
    if (!wi || !wo || !index || !merl_coords(wi, wo, u)) return 0;
    *index = cell_at(clamp_index(u[0], SB_MERL_TH), clamp_index(u[1], SB_MERL_TD), clamp_index(u[2], SB_MERL_PD));
    return 1;
}

int sb_merl_cell_dirs(size_t index, double wi[3], double wo[3]) {
    if (index >= SB_MERL_CELLS || !wi || !wo) return 0;
    size_t ip = index % SB_MERL_PD, id = index / SB_MERL_PD % SB_MERL_TD, ih = index / SB_MERL_PD / SB_MERL_TD;
    double uh = ((double)ih + 0.5) / SB_MERL_TH;
    return sb_half_diff_dirs(uh * uh * (SB_PI / 2), ((double)id + 0.5) / SB_MERL_TD * (SB_PI / 2),
                             ((double)ip + 0.5) / SB_MERL_PD * SB_PI, wi, wo);
}

/* ---- the source -------------------------------------------------------- */

typedef struct merl {
    double *v; /* 3 planes of SB_MERL_CELLS, scaled f_r, NaN = missing */
    sb_interp_t interp;
} merl_t;

static void merl_destroy(void *self) {
    merl_t *m = self;
    if (!m) return;
    free(m->v);
    free(m);
}

static int merl_eval_nearest(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const merl_t *m = self;
    size_t k;
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!sb_merl_index(wi, wo, &k)) return 0;
    double v[3];
    for (int c = 0; c < 3; c++) {
        v[c] = m->v[(size_t)c * SB_MERL_CELLS + k];
        if (isnan(v[c])) return 0;
    }
    memcpy(rgb, v, sizeof v);
    return 1;
}

/* Trilinear between cell centres: u - 1/2 on each axis; theta axes clamp at
 * the first and last centres, phi_d wraps (period pi).  Missing corners are
 * skipped and the remaining weights renormalised; no corner: missing. */
static int merl_eval_linear(const void *self, const double wi[3], const double wo[3], double rgb[3]) {
    const merl_t *m = self;
    double u[3];
    rgb[0] = rgb[1] = rgb[2] = 0;
    if (!merl_coords(wi, wo, u)) return 0;
    static const size_t n[3] = {SB_MERL_TH, SB_MERL_TD, SB_MERL_PD};
    size_t i0[3], i1[3];
    double t[3];
    for (int a = 0; a < 3; a++) {
        double x = u[a] - 0.5;
        if (a < 2) {
            if (!(x > 0)) x = 0;
            if (x > (double)(n[a] - 1)) x = (double)(n[a] - 1);
            i0[a] = (size_t)x;
            if (i0[a] >= n[a] - 1) i0[a] = n[a] - 1;
            t[a] = x - (double)i0[a];
            i1[a] = i0[a] + 1 < n[a] ? i0[a] + 1 : i0[a];
        } else {
            double f = floor(x);
            t[a] = x - f;
            long long k = (long long)f % (long long)n[a];
            if (k < 0) k += (long long)n[a];
            i0[a] = (size_t)k;
            i1[a] = (i0[a] + 1) % n[a];
        }
    }
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (int corner = 0; corner < 8; corner++) {
        size_t ih = corner & 1 ? i1[0] : i0[0], id = corner & 2 ? i1[1] : i0[1], ip = corner & 4 ? i1[2] : i0[2];
        double w = (corner & 1 ? t[0] : 1 - t[0]) * (corner & 2 ? t[1] : 1 - t[1]) * (corner & 4 ? t[2] : 1 - t[2]);
        if (w <= 0) continue;
        size_t k = cell_at(ih, id, ip);
        double v0 = m->v[k], v1 = m->v[SB_MERL_CELLS + k], v2 = m->v[2 * SB_MERL_CELLS + k];
        if (isnan(v0) || isnan(v1) || isnan(v2)) continue;
        acc[0] += w * v0;
        acc[1] += w * v1;
        acc[2] += w * v2;
        wsum += w;
    }
    if (!(wsum > 0)) return 0;
    for (int c = 0; c < 3; c++)
        rgb[c] = acc[c] / wsum;
    return 1;
}

static double le_f64(const unsigned char *b) {
    uint64_t u = 0;
    for (int k = 7; k >= 0; k--)
        u = u << 8 | b[k];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static void put_le_f64(unsigned char *b, double d) {
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int k = 0; k < 8; k++)
        b[k] = (unsigned char)(u >> (8 * k));
}

/* The samples: every measured cell at its centre (index space + 1/2). */
static size_t merl_sample_count(const void *self) {
    (void)self;
    return SB_MERL_CELLS;
}
static int merl_sample(const void *self, size_t k, double wi[3], double wo[3], double f[3]) {
    const merl_t *m = self;
    if (isnan(m->v[k]) || !sb_merl_cell_dirs(k, wi, wo)) return 0;
    for (int c = 0; c < 3; c++)
        f[c] = m->v[(size_t)c * SB_MERL_CELLS + k];
    return 1;
}

/* The header (dims 90 x 90 x 180) and the file size, checked before
 * anything else is read. */
static sb_result_t merl_check_head(sb_context_t *ctx, const char *path, FILE *fp) {
    struct stat st;
    if (fstat(fileno(fp), &st) != 0) return sb_error(ctx, SB_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
    unsigned char head[12];
    size_t got = fread(head, 1, sizeof head, fp);
    if (got < sizeof head)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: MERL: truncated header, %zu of 12 bytes", path, got);
    int32_t dims[3];
    for (int k = 0; k < 3; k++) {
        uint32_t u = (uint32_t)head[4 * k] | (uint32_t)head[4 * k + 1] << 8 | (uint32_t)head[4 * k + 2] << 16 |
                     (uint32_t)head[4 * k + 3] << 24;
        dims[k] = (int32_t)u;
    }
    if (dims[0] != SB_MERL_TH || dims[1] != SB_MERL_TD || dims[2] != SB_MERL_PD)
        return sb_error(ctx, SB_ERR_FORMAT, "%s: MERL: dims %ld x %ld x %ld, expected %d x %d x %d", path,
                        (long)dims[0], (long)dims[1], (long)dims[2], SB_MERL_TH, SB_MERL_TD, SB_MERL_PD);
    if ((uintmax_t)st.st_size != SB_MERL_FILE_SIZE)
        return sb_error(ctx, SB_ERR_FORMAT,
                        "%s: MERL: file size %jd bytes, expected %zu (12-byte header + 3 x %zu float64) for dims "
                        "90 x 90 x 180",
                        path, (intmax_t)st.st_size, SB_MERL_FILE_SIZE, SB_MERL_CELLS);
    return SB_OK;
}

/* The 3 x SB_MERL_CELLS little-endian doubles after the header into v. */
static sb_result_t merl_read_values(sb_context_t *ctx, const char *path, FILE *fp, double *v) {
    const size_t chunk = 1 << 16;
    unsigned char *buf = malloc(chunk * 8);
    if (!buf) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    sb_result_t r = SB_OK;
    for (size_t at = 0; at < 3 * SB_MERL_CELLS;) {
        size_t n = 3 * SB_MERL_CELLS - at < chunk ? 3 * SB_MERL_CELLS - at : chunk;
        if (fread(buf, 8, n, fp) != n) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s: MERL: truncated at value %zu of %zu", path, at, 3 * SB_MERL_CELLS);
            break;
        }
        for (size_t k = 0; k < n; k++)
            v[at + k] = le_f64(buf + 8 * k);
        at += n;
    }
    free(buf);
    return r;
}

/* Classify the cells: a negative or non-finite channel makes a cell missing
 * (NAN in every channel); the others are scaled to f_r (sb_merl_scale) and
 * counted into info's statistics. */
static sb_result_t merl_scan(sb_context_t *ctx, const char *path, double *v, sb_measured_info_t *info) {
    double sum[3] = {0, 0, 0};
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    for (size_t k = 0; k < SB_MERL_CELLS; k++) {
        int neg = 0, nan = 0;
        for (int c = 0; c < 3; c++) {
            double x = v[(size_t)c * SB_MERL_CELLS + k];
            if (!isfinite(x))
                nan = 1;
            else if (x < 0)
                neg = 1;
        }
        if (neg || nan) {
            info->missing++;
            info->negative += (size_t)neg;
            info->nan_rows += (size_t)nan;
            for (int c = 0; c < 3; c++)
                v[(size_t)c * SB_MERL_CELLS + k] = NAN;
            continue;
        }
        info->samples++;
        for (int c = 0; c < 3; c++) {
            double x = v[(size_t)c * SB_MERL_CELLS + k] * sb_merl_scale[c];
            if (x > FLT_MAX)
                return sb_error(ctx, SB_ERR_FORMAT,
                                "%s: MERL: cell %zu (theta_h %zu, theta_d %zu, phi_d %zu) channel %d: f_r = %g (1/sr) "
                                "overflows float storage (largest %g): not a reflectance",
                                path, k, k / (SB_MERL_TD * SB_MERL_PD), k / SB_MERL_PD % SB_MERL_TD, k % SB_MERL_PD, c,
                                x, (double)FLT_MAX);
            v[(size_t)c * SB_MERL_CELLS + k] = x;
            sum[c] += x;
            if (x < info->value_min[c]) info->value_min[c] = x;
            if (x > info->value_max[c]) info->value_max[c] = x;
        }
    }
    if (!info->samples)
        return sb_error(ctx, SB_ERR_FORMAT,
                        "%s: MERL: no measured cell (all %zu missing: %zu negative, %zu NaN or infinite)", path,
                        info->rows, info->negative, info->nan_rows);
    for (int c = 0; c < 3; c++)
        info->value_mean[c] = sum[c] / (double)info->samples;
    return SB_OK;
}

/* The source over m (owned by it from here on) and the rest of info. */
static sb_result_t merl_source(sb_context_t *ctx, const char *path, merl_t *m, sb_measured_info_t *info,
                               sb_source_t **out) {
    sb_interp_t interp = m->interp;
    info->theta_i_max = info->theta_o_max = SB_PI / 2;
    info->interp = interp;
    info->flags = SB_SOURCE_MEASURED | SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL;
    sb_info_field(info, "cells", (double)info->rows,
                  "%zu (measured %zu, missing %zu: negative %zu, NaN or infinite %zu)", info->rows, info->samples,
                  info->missing, info->negative, info->nan_rows);
    sb_info_field(info, "interp", NAN, "%s", sb_interp_name(interp));
    char *desc = sb_format("merl:%s (%s)", path, sb_interp_name(interp)); /* paths of any length */
    sb_source_ops_t ops = {interp == SB_INTERP_LINEAR ? merl_eval_linear : merl_eval_nearest, merl_destroy};
    sb_result_t r = desc ? sb_source_create(ctx, &ops, m, info->flags, desc, out) : SB_ERR_NOMEM;
    free(desc);
    if (r != SB_OK) {
        merl_destroy(m);
        return r;
    }
    sb_source_set_samples_(*out, merl_sample_count, merl_sample);
    return SB_OK;
}

static sb_result_t merl_open(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                             sb_measured_info_t *info) {
    sb_interp_t interp = o->interp == SB_INTERP_DEFAULT ? SB_INTERP_NEAREST : o->interp;
    if (interp != SB_INTERP_NEAREST && interp != SB_INTERP_LINEAR)
        return sb_error(ctx, SB_ERR_ARG, "%s: MERL tables interpolate 'nearest' or 'linear', not '%s'", path,
                        sb_interp_name(interp));
    sb_result_t r;
    FILE *fp = sb_fopen_regular(ctx, path, "MERL table", SB_MEASURED_MAX_FILE, &r);
    if (!fp) return r;
    merl_t *m = NULL;
    r = merl_check_head(ctx, path, fp);
    if (r == SB_OK && !(m = calloc(1, sizeof *m))) r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", path);
    if (r == SB_OK) {
        m->interp = interp;
        m->v = sb_alloc(ctx, 3 * SB_MERL_CELLS, sizeof(double), path);
        r = m->v ? merl_read_values(ctx, path, fp, m->v) : SB_ERR_NOMEM;
    }
    fclose(fp);
    if (r == SB_OK) {
        info->rows = SB_MERL_CELLS;
        info->channels = 3;
        r = merl_scan(ctx, path, m->v, info);
    }
    if (r != SB_OK) {
        merl_destroy(m);
        return r;
    }
    return merl_source(ctx, path, m, info, out);
}

/* A MERL header: the dims 90, 90, 180 as little-endian int32. */
static int merl_sniff(const unsigned char *h, size_t n) {
    static const unsigned char dims[12] = {SB_MERL_TH, 0, 0, 0, SB_MERL_TD, 0, 0, 0, SB_MERL_PD, 0, 0, 0};
    return n >= 12 && memcmp(h, dims, 12) == 0 ? 2 : 0;
}

const sb_reader_t sb_reader_merl = {"merl", "MERL .binary", ".binary", merl_sniff, merl_open};

/* ---- writer ------------------------------------------------------------ */

typedef struct merl_job {
    const sb_source_t *src;
    double *v; /* 3 planes of stored values */
    size_t h0, h1;
    double above;             /* f_r beyond which a cell counts in st.above (inf: none) */
    int keep;                 /* write the cells above as evaluated, else as missing */
    double z_min;             /* cells whose light has cos theta_i <= this are missing (0: none) */
    sb_merl_write_stats_t st; /* this thread's share */
} merl_job_t;

static void *merl_fill(void *arg) {
    merl_job_t *j = arg;
    double wi[3], wo[3], rgb[3];
    for (size_t k = j->h0 * SB_MERL_TD * SB_MERL_PD; k < j->h1 * SB_MERL_TD * SB_MERL_PD; k++) {
        int ok = sb_merl_cell_dirs(k, wi, wo) && sb_source_eval(j->src, wi, wo, rgb);
        if (ok && wi[2] <= j->z_min) {
            j->st.grazing++;
            ok = 0;
        }
        for (int c = 0; c < 3 && ok; c++)
            ok = isfinite(rgb[c]);
        double m = ok ? fmax(rgb[0], fmax(rgb[1], rgb[2])) : 0;
        if (m > j->above) {
            size_t td = (k / SB_MERL_PD) % SB_MERL_TD;
            j->st.above++;
            if (td < j->st.above_td_min) j->st.above_td_min = td;
            if (m > j->st.above_max) j->st.above_max = m;
            ok = j->keep;
        }
        for (int c = 0; c < 3; c++)
            j->v[(size_t)c * SB_MERL_CELLS + k] = ok ? rgb[c] / sb_merl_scale[c] : -1.0;
        j->st.written += (size_t)ok;
        if (ok && m > j->st.value_max) j->st.value_max = m;
    }
    return NULL;
}

sb_result_t sb_merl_write(sb_context_t *ctx, const char *path, const sb_source_t *src) {
    return sb_merl_write_stats(ctx, path, src, NULL, NULL);
}

sb_result_t sb_merl_write_stats(sb_context_t *ctx, const char *path, const sb_source_t *src,
                                const sb_write_opts_t *opts, sb_merl_write_stats_t *stats) {
    if (!path || !src) return sb_error(ctx, SB_ERR_ARG, "merl write: missing path or source");
    const sb_measured_info_t *in = sb_measured_source_info(src);
    double vmax = in ? fmax(in->value_max[0], fmax(in->value_max[1], in->value_max[2])) : INFINITY;
    /* the light's margin from the horizon, for a source that stores f cos theta_i */
    double margin = opts && opts->horizon_deg != 0 ? opts->horizon_deg : 1;
    if (!(margin < 90))
        return sb_error(ctx, SB_ERR_RANGE, "merl write: horizon %g deg out of range, need < 90", margin);
    if (!(sb_source_flags(src) & SB_SOURCE_STORES_COS) || margin < 0) margin = 0;
    double z_min = margin > 0 ? sin(margin * SB_PI / 180) : 0;
    char tmp[4200];
    if (sb_tmp_name(path, tmp, sizeof tmp) != 0) return sb_error(ctx, SB_ERR_ARG, "%s: path too long", path);
    double *v = sb_alloc(ctx, 3 * SB_MERL_CELLS, sizeof(double), "merl write");
    if (!v) return SB_ERR_NOMEM;
    /* Evaluate: theta_h slices split among threads. */
    int nt = sb_threads_for(0, SB_MERL_TH, SB_MERL_TH, 0);
    merl_job_t jobs[SB_THREADS_MAX];
    for (int t = 0; t < nt; t++) {
        jobs[t] = (merl_job_t){src, v, 0, 0, vmax > 0 ? vmax : INFINITY, opts && opts->keep_extrapolated, z_min, {0}};
        jobs[t].st.above_td_min = SB_MERL_TD;
        sb_part(SB_MERL_TH, t, nt, &jobs[t].h0, &jobs[t].h1);
    }
    sb_parallel_run(merl_fill, jobs, sizeof *jobs, nt, NULL, NULL);
    sb_merl_write_stats_t st = {SB_MERL_CELLS, 0, 0, 0, in && vmax > 0 ? vmax : NAN, SB_MERL_TD, 0, 0, margin};
    for (int t = 0; t < nt; t++) {
        st.written += jobs[t].st.written;
        st.above += jobs[t].st.above;
        st.grazing += jobs[t].st.grazing;
        st.value_max = fmax(st.value_max, jobs[t].st.value_max);
        st.above_max = fmax(st.above_max, jobs[t].st.above_max);
        if (jobs[t].st.above_td_min < st.above_td_min) st.above_td_min = jobs[t].st.above_td_min;
    }
    if (stats) *stats = st;
    /* Encode and write under the temporary name, then rename. */
    FILE *fp = fopen(tmp, "wb");
    if (!fp) {
        free(v);
        return sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, strerror(errno));
    }
    unsigned char head[12], buf[8 * 4096];
    const int32_t dims[3] = {SB_MERL_TH, SB_MERL_TD, SB_MERL_PD};
    for (int k = 0; k < 3; k++)
        for (int b = 0; b < 4; b++)
            head[4 * k + b] = (unsigned char)((uint32_t)dims[k] >> (8 * b));
    int ok = fwrite(head, 1, sizeof head, fp) == sizeof head;
    for (size_t at = 0; ok && at < 3 * SB_MERL_CELLS;) {
        size_t n = 3 * SB_MERL_CELLS - at < 4096 ? 3 * SB_MERL_CELLS - at : 4096;
        for (size_t k = 0; k < n; k++)
            put_le_f64(buf + 8 * k, v[at + k]);
        ok = fwrite(buf, 8, n, fp) == n;
        at += n;
    }
    free(v);
    if (fflush(fp) != 0 || ferror(fp)) ok = 0;
    if (fclose(fp) != 0) ok = 0;
    if (!ok || rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return sb_error(ctx, SB_ERR_IO, "%s: cannot write: %s", path, strerror(e));
    }
    return SB_OK;
}
