/* Scattered gonioreflectometer tables (Cornell .brdf, ALTA, sepbrdf CSV):
 * the text readers.  The samples they read become an interpolated source
 * in scattered.c; the simulated gonioreflectometer that writes such
 * tables is in gonio_sim.c. */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "source/measured_impl.h"
#include "util/internal.h"

#define MAX_WAVELENGTHS 4096

/* ---- readers ------------------------------------------------------------ */

typedef struct reader {
    sb_context_t *ctx;
    const char *path;
    sb_lines_t lr;
    sb_samples_t ss;
    sb_measured_info_t *info;
} reader_t;

/* One row: classify (NaN, horizon), then keep.  Angles must be finite. */
static sb_result_t reader_add(reader_t *rd, const double wi[3], const double wo[3], const double f[3], int nan,
                              int negative) {
    rd->info->rows++;
    if (nan) {
        rd->info->nan_rows++;
        return SB_OK;
    }
    if (!(wi[2] > SB_HORIZON_Z && wo[2] > SB_HORIZON_Z)) {
        rd->info->horizon_rows++;
        return SB_OK;
    }
    for (int c = 0; c < 3; c++)
        if (fabs(f[c]) > FLT_MAX)
            return sb_error(rd->ctx, SB_ERR_FORMAT,
                            "%s:%zu: f_r = %g (1/sr) overflows float storage (largest %g): not a reflectance", rd->path,
                            rd->lr.line, f[c], (double)FLT_MAX);
    rd->info->negative += (size_t)(negative != 0);
    double g[3] = {f[0], f[1], f[2]};
    if (rd->info->wavelengths) rd->info->out_of_gamut += (size_t)sb_gamut_map(rd->info->gamut, g);
    return sb_samples_push_(rd->ctx, rd->path, &rd->ss, wi, wo, g, rd->info);
}

static sb_result_t bad_number(reader_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not a number", rd->path, rd->lr.line, what, field);
}
static sb_result_t not_finite(reader_t *rd, const char *what, const char *field) {
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' is not finite", rd->path, rd->lr.line, what, field);
}

/* Domains of the angles in a row (radians, a rounding slack of 1e-9):
 * an elevation lies in [0, pi] (above pi/2 it is below the horizon: the
 * row is skipped and counted), an azimuth in [-2 pi, 2 pi], an ALTA
 * projection theta_v cos/sin(dphi) in [-pi, pi].  Anything else is not an
 * angle of a direction: refused with the file and line. */
typedef enum angle_kind { ANGLE_THETA, ANGLE_PHI, ANGLE_PROJ } angle_kind_t;

/* Parse an angle field (finite, in its domain), times `unit`. */
static sb_result_t angle_field(reader_t *rd, const char *what, const char *s, double unit, angle_kind_t kind,
                               double *out) {
    if (sb_parse_number(s, out) != 0) return bad_number(rd, what, s);
    if (!isfinite(*out)) return not_finite(rd, what, s);
    *out *= unit;
    double lo = kind == ANGLE_THETA ? 0 : kind == ANGLE_PHI ? -2 * SB_PI : -SB_PI;
    double hi = kind == ANGLE_PHI ? 2 * SB_PI : SB_PI;
    if (!(*out >= lo - 1e-9 && *out <= hi + 1e-9))
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %s '%.40s' (%g deg) is outside %g..%g deg", rd->path,
                        rd->lr.line, what, s, *out * 180 / SB_PI, lo * 180 / SB_PI, hi * 180 / SB_PI);
    if (kind == ANGLE_THETA && *out < 0) *out = 0;
    return SB_OK;
}

/* Parse a value field: NaN marks a missing value (*nan = 1), inf is an error. */
static sb_result_t value_field(reader_t *rd, const char *what, const char *s, double *out, int *nan) {
    if (sb_parse_number(s, out) != 0) return bad_number(rd, what, s);
    if (isnan(*out))
        *nan = 1;
    else if (!isfinite(*out))
        return not_finite(rd, what, s);
    return SB_OK;
}

static int is_blank_or_comment(const char *s, char comment) {
    while (*s == ' ' || *s == '\t')
        s++;
    return *s == 0 || *s == comment;
}

/* Cornell / pbrt .brdf state: n wavelengths (have read so far), their
 * XYZ-to-RGB weights w (3 x n), one row's values and fields. */
typedef struct cornell {
    size_t n, have;
    double *wl, *w, *vals;
    char **fields;
} cornell_t;

/* The wavelength count line: allocate for n wavelengths. */
static sb_result_t cornell_count(reader_t *rd, char *line, cornell_t *cn) {
    char *f[2];
    size_t nf = sb_split_fields(line, 0, f, 2);
    double v;
    if (nf != 1 || sb_parse_number(f[0], &v) != 0 || !(v >= 1 && v <= MAX_WAVELENGTHS) || v != floor(v))
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: wavelength count '%.40s' is not an integer in 1..%d", rd->path,
                        rd->lr.line, nf ? f[0] : "", MAX_WAVELENGTHS);
    size_t n = cn->n = (size_t)v;
    cn->wl = malloc(n * sizeof *cn->wl);
    cn->w = malloc(3 * n * sizeof *cn->w);
    cn->vals = malloc(n * sizeof *cn->vals);
    cn->fields = malloc((n + 5) * sizeof *cn->fields);
    if (!cn->wl || !cn->w || !cn->vals || !cn->fields)
        return sb_error(rd->ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
    return SB_OK;
}

/* A line of wavelengths (increasing, positive); after the last one the
 * spectral weights.  *done when all n are read. */
static sb_result_t cornell_wavelengths(reader_t *rd, char *line, const sb_measured_opts_t *o, cornell_t *cn,
                                       int *done) {
    sb_context_t *ctx = rd->ctx;
    double *wl = cn->wl;
    size_t n = cn->n, nf = sb_split_fields(line, 0, cn->fields, n + 5);
    if (cn->have + nf > n)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: more wavelengths than the %zu announced", rd->path, rd->lr.line,
                        n);
    for (size_t k = 0; k < nf; k++) {
        size_t h = cn->have;
        if (sb_parse_number(cn->fields[k], &wl[h]) != 0) return bad_number(rd, "wavelength", cn->fields[k]);
        if (!isfinite(wl[h]) || wl[h] <= 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength '%.40s' is not a positive number", rd->path,
                            rd->lr.line, cn->fields[k]);
        if (h > 0 && !(wl[h] > wl[h - 1]))
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths not increasing (%g nm after %g nm)", rd->path,
                            rd->lr.line, wl[h], wl[h - 1]);
        cn->have++;
    }
    *done = cn->have == n;
    if (!*done) return SB_OK;
    if (wl[n - 1] < 380 || wl[0] > 780)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths %g..%g nm miss the visible range 380..780 nm",
                        rd->path, rd->lr.line, wl[0], wl[n - 1]);
    sb_result_t r = sb_spectral_weights(ctx, wl, n, o->white, cn->w);
    if (r != SB_OK) return r;
    rd->info->wavelengths = n;
    rd->info->channels = n;
    rd->info->wl_min = wl[0];
    rd->info->wl_max = wl[n - 1];
    return SB_OK;
}

/* A row: 4 angles and n spectral values, weighted into RGB. */
static sb_result_t cornell_row(reader_t *rd, char *line, cornell_t *cn) {
    size_t n = cn->n, nf = sb_split_fields(line, 0, cn->fields, n + 5);
    if (nf != 4 + n)
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (4 angles + %zu spectral values)",
                        rd->path, rd->lr.line, nf, 4 + n, n);
    static const char *const an[4] = {"theta_i", "phi_i", "theta_s", "phi_s"};
    double a[4];
    sb_result_t r;
    for (int k = 0; k < 4; k++)
        if ((r = angle_field(rd, an[k], cn->fields[k], 1, k % 2 ? ANGLE_PHI : ANGLE_THETA, &a[k])) != SB_OK) return r;
    int nan = 0;
    for (size_t k = 0; k < n; k++)
        if ((r = value_field(rd, "spectral value", cn->fields[4 + k], &cn->vals[k], &nan)) != SB_OK) return r;
    double wi[3], wo[3], f[3] = {0, 0, 0};
    sb_dir_from_angles(a[0], a[1], wi);
    sb_dir_from_angles(a[2], a[3], wo);
    int neg = 0;
    for (size_t k = 0; k < n && !nan; k++)
        neg |= cn->vals[k] < 0;
    for (int c = 0; c < 3 && !nan; c++)
        for (size_t k = 0; k < n; k++)
            f[c] += cn->w[(size_t)c * n + k] * cn->vals[k];
    return reader_add(rd, wi, wo, f, nan, neg);
}

/* Cornell / pbrt .brdf: count, wavelengths (may span lines), then rows of
 * 4 + n numbers.  Lines starting with '#' are comments. */
static sb_result_t read_cornell(reader_t *rd, const sb_measured_opts_t *o) {
    cornell_t cn = {0, 0, NULL, NULL, NULL, NULL};
    sb_result_t r = SB_OK;
    char *line;
    int st = 0, state = 0;
    while (r == SB_OK && (st = sb_lines_next(rd->ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, '#')) continue;
        int done = 0;
        if (state == 0) {
            if ((r = cornell_count(rd, line, &cn)) == SB_OK) state = 1;
        } else if (state == 1) {
            if ((r = cornell_wavelengths(rd, line, o, &cn, &done)) == SB_OK && done) state = 2;
        } else {
            r = cornell_row(rd, line, &cn);
        }
    }
    if (r == SB_OK && st >= 0 && state < 2)
        r = sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: ends before the %s", rd->path, rd->lr.line,
                     state == 0 ? "wavelength count" : "last wavelength");
    free(cn.wl);
    free(cn.w);
    free(cn.vals);
    free(cn.fields);
    return r;
}

/* ALTA input parameterisations (ALTA's params.h names; angles in
 * radians, l the light = incoming direction wi, v the view = outgoing
 * wo): the row's din inputs, their kinds, whether a pair's absolute
 * azimuth is given (the table may be anisotropic), and the directions. */
typedef struct alta_param {
    const char *name;
    int din;
    const char *what[6];
    angle_kind_t kind[6]; /* ANGLE_NONE: a Cartesian component */
    int azimuth;          /* the pair's azimuth about the normal is in the row */
    void (*dirs)(const double *a, double wi[3], double wo[3]);
} alta_param_t;

/* theta_l, theta_v cos(dphi), theta_v sin(dphi) */
static void alta_proj(const double *a, double wi[3], double wo[3]) {
    sb_dir_from_angles(a[0], 0, wi);
    sb_dir_from_angles(hypot(a[1], a[2]), atan2(a[2], a[1]), wo);
}
/* theta_v, theta_l, dphi */
static void alta_tv_tl(const double *a, double wi[3], double wo[3]) {
    sb_dir_from_angles(a[1], 0, wi);
    sb_dir_from_angles(a[0], a[2], wo);
}
/* Rusinkiewicz (sb_dirs_from_halfdiff), phi_h = 0 without it */
static void alta_rusin3(const double *a, double wi[3], double wo[3]) {
    sb_dirs_from_halfdiff(a[0], 0, a[1], a[2], wi, wo);
}
static void alta_rusin4(const double *a, double wi[3], double wo[3]) {
    sb_dirs_from_halfdiff(a[0], a[1], a[2], a[3], wi, wo);
}
/* theta_l, phi_l, theta_v, phi_v */
static void alta_spherical(const double *a, double wi[3], double wo[3]) {
    sb_dir_from_angles(a[0], a[1], wi);
    sb_dir_from_angles(a[2], a[3], wo);
}
/* l_x, l_y, l_z, v_x, v_y, v_z (normalised) */
static void alta_cartesian(const double *a, double wi[3], double wo[3]) {
    double nl = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), nv = sqrt(a[3] * a[3] + a[4] * a[4] + a[5] * a[5]);
    for (int i = 0; i < 3; i++) {
        wi[i] = a[i] / nl;
        wo[i] = a[3 + i] / nv;
    }
}

#define ANGLE_NONE ((angle_kind_t)-1)
static const alta_param_t alta_params[] = {
    {"ISOTROPIC_TL_TV_PROJ_DPHI",
     3,
     {"theta_l", "theta_v cos(dphi)", "theta_v sin(dphi)"},
     {ANGLE_THETA, ANGLE_PROJ, ANGLE_PROJ},
     0,
     alta_proj},
    {"ISOTROPIC_TV_TL_DPHI", 3, {"theta_v", "theta_l", "dphi"}, {ANGLE_THETA, ANGLE_THETA, ANGLE_PHI}, 0, alta_tv_tl},
    {"RUSIN_TH_TD_PD", 3, {"theta_h", "theta_d", "phi_d"}, {ANGLE_THETA, ANGLE_THETA, ANGLE_PHI}, 0, alta_rusin3},
    {"RUSIN_TH_PH_TD_PD",
     4,
     {"theta_h", "phi_h", "theta_d", "phi_d"},
     {ANGLE_THETA, ANGLE_PHI, ANGLE_THETA, ANGLE_PHI},
     1,
     alta_rusin4},
    {"SPHERICAL_TL_PL_TV_PV",
     4,
     {"theta_l", "phi_l", "theta_v", "phi_v"},
     {ANGLE_THETA, ANGLE_PHI, ANGLE_THETA, ANGLE_PHI},
     1,
     alta_spherical},
    {"CARTESIAN",
     6,
     {"l_x", "l_y", "l_z", "v_x", "v_y", "v_z"},
     {ANGLE_NONE, ANGLE_NONE, ANGLE_NONE, ANGLE_NONE, ANGLE_NONE, ANGLE_NONE},
     1,
     alta_cartesian},
};
#define ALTA_PARAMS (sizeof alta_params / sizeof alta_params[0])

/* The names read, "A, B, ..." into buf. */
static const char *alta_param_names(char *buf, size_t size) {
    size_t at = 0;
    buf[0] = 0;
    for (size_t k = 0; k < ALTA_PARAMS && at < size; k++)
        at += (size_t)snprintf(buf + at, size - at, "%s%s", k ? ", " : "", alta_params[k].name);
    return buf;
}

/* ALTA header state: #DIM (din, dout), #PARAM_IN (its entry), #PARAM_OUT
 * with the cosine factor (1) or without (0); -1 / NULL while not given;
 * the first row's azimuth and whether another differs (anisotropic). */
typedef struct alta {
    long din, dout;
    const alta_param_t *in;
    int cosine;
    double azimuth0;
    int have_azimuth, azimuth_varies;
} alta_t;

/* #DIM and #PARAM_IN agree (both given). */
static sb_result_t alta_dims(reader_t *rd, const alta_t *al) {
    if (al->din < 0 || !al->in || al->din == al->in->din) return SB_OK;
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: #PARAM_IN %s has %d inputs, #DIM says %ld", rd->path, rd->lr.line,
                    al->in->name, al->in->din, al->din);
}

/* A '#' line of the header (fields f, nf of them): checks what sepbrdf
 * reads; other comments (#SAMPLE, #ORIGIN, #URL, ...) pass. */
static sb_result_t alta_header(reader_t *rd, char **f, size_t nf, alta_t *al) {
    sb_context_t *ctx = rd->ctx;
    char names[256];
    if (strcmp(f[0], "#DIM") == 0) {
        char *e1 = NULL, *e2 = NULL;
        if (nf == 3) {
            al->din = strtol(f[1], &e1, 10);
            al->dout = strtol(f[2], &e2, 10);
        }
        if (nf != 3 || *e1 || *e2)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: #DIM needs two integers", rd->path, rd->lr.line);
        if (al->din >= 1 && al->din <= 2)
            return sb_error(ctx, SB_ERR_UNSUPPORTED,
                            "%s:%zu: ALTA #DIM %ld %ld: a table of %ld input%s (a slice such as f(cos theta_h) at "
                            "one theta_d), not a BRDF of both directions; sepbrdf reads tables of 3, 4 or 6 inputs "
                            "(#PARAM_IN %s) and 1 or 3 outputs",
                            rd->path, rd->lr.line, al->din, al->dout, al->din, al->din == 1 ? "" : "s",
                            alta_param_names(names, sizeof names));
        if ((al->din != 3 && al->din != 4 && al->din != 6) || (al->dout != 1 && al->dout != 3))
            return sb_error(ctx, SB_ERR_UNSUPPORTED,
                            "%s:%zu: ALTA #DIM %ld %ld not supported; need 3, 4 or 6 inputs (#PARAM_IN %s) and 1 or 3 "
                            "outputs",
                            rd->path, rd->lr.line, al->din, al->dout, alta_param_names(names, sizeof names));
        return alta_dims(rd, al);
    } else if (strcmp(f[0], "#PARAM_IN") == 0) {
        al->in = NULL;
        for (size_t k = 0; k < ALTA_PARAMS && nf >= 2; k++)
            if (strcmp(f[1], alta_params[k].name) == 0) al->in = &alta_params[k];
        if (!al->in)
            return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s:%zu: ALTA #PARAM_IN %s not supported; need one of %s",
                            rd->path, rd->lr.line, nf >= 2 ? f[1] : "(none)", alta_param_names(names, sizeof names));
        return alta_dims(rd, al);
    } else if (strcmp(f[0], "#PARAM_OUT") == 0) {
        if (nf >= 2 && strcmp(f[1], "INV_STERADIAN_COSINE_FACTOR") == 0)
            al->cosine = 1;
        else if (nf >= 2 && (strcmp(f[1], "INV_STERADIAN") == 0 || strcmp(f[1], "RGB_COLOR") == 0))
            al->cosine = 0;
        else
            return sb_error(ctx, SB_ERR_UNSUPPORTED,
                            "%s:%zu: ALTA #PARAM_OUT %s not supported; need INV_STERADIAN_COSINE_FACTOR, "
                            "INV_STERADIAN or RGB_COLOR",
                            rd->path, rd->lr.line, nf >= 2 ? f[1] : "(none)");
    } else if (strcmp(f[0], "#VS") == 0) {
        if (nf != 2 || strcmp(f[1], "0") != 0)
            return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s:%zu: ALTA confidence columns (#VS %s) not supported", rd->path,
                            rd->lr.line, nf >= 2 ? f[1] : "");
    }
    return SB_OK;
}

/* A data row: the din inputs of #PARAM_IN, dout values. */
static sb_result_t alta_row(reader_t *rd, char *s, alta_t *al) {
    sb_context_t *ctx = rd->ctx;
    if (al->din < 0 || !al->in || al->cosine < 0)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: data before the ALTA header (#DIM, #PARAM_IN, #PARAM_OUT)",
                        rd->path, rd->lr.line);
    const alta_param_t *pa = al->in;
    char *f[12];
    size_t nf = sb_split_fields(s, 0, f, 12), want = (size_t)pa->din + (size_t)al->dout;
    if (nf != want)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (%d inputs + %ld values)", rd->path,
                        rd->lr.line, nf, want, pa->din, al->dout);
    double a[6], v[3];
    sb_result_t r;
    for (int k = 0; k < pa->din; k++) {
        if (pa->kind[k] != ANGLE_NONE) {
            if ((r = angle_field(rd, pa->what[k], f[k], 1, pa->kind[k], &a[k])) != SB_OK) return r;
        } else if (sb_parse_number(f[k], &a[k]) != 0) {
            return bad_number(rd, pa->what[k], f[k]);
        } else if (!isfinite(a[k])) {
            return not_finite(rd, pa->what[k], f[k]);
        }
    }
    if (pa->dirs == alta_proj && hypot(a[1], a[2]) > SB_PI + 1e-9)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: theta_v = |(%s, %s)| = %g deg is outside 0..180 deg", rd->path,
                        rd->lr.line, f[1], f[2], hypot(a[1], a[2]) * 180 / SB_PI);
    if (pa->dirs == alta_cartesian)
        for (int k = 0; k < 2; k++) {
            double n = sqrt(a[3 * k] * a[3 * k] + a[3 * k + 1] * a[3 * k + 1] + a[3 * k + 2] * a[3 * k + 2]);
            if (!(fabs(n - 1) <= 1e-3))
                return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %s direction has length %g, not a unit vector", rd->path,
                                rd->lr.line, k ? "view" : "light", n);
        }
    int nan = 0;
    for (long k = 0; k < al->dout; k++)
        if ((r = value_field(rd, "value", f[pa->din + k], &v[k], &nan)) != SB_OK) return r;
    if (al->dout == 1) v[1] = v[2] = v[0];
    double wi[3], wo[3];
    pa->dirs(a, wi, wo);
    if (pa->azimuth) { /* the pair's azimuth (phi_h, phi_l): isotropic tables keep one, e.g. phi_l = 0 */
        double az = NAN;
        if (pa->dirs != alta_cartesian && a[0] > 1e-12) az = a[1]; /* undefined at the pole */
        if (pa->dirs == alta_cartesian && hypot(a[0], a[1]) > 1e-12) az = atan2(a[1], a[0]);
        if (isfinite(az) && !al->have_azimuth) al->azimuth0 = az, al->have_azimuth = 1;
        if (isfinite(az) && fabs(remainder(az - al->azimuth0, 2 * SB_PI)) > 1e-9) al->azimuth_varies = 1;
    }
    /* INV_STERADIAN_COSINE_FACTOR: the value is f_r cos(theta_v) */
    int neg = v[0] < 0 || v[1] < 0 || v[2] < 0;
    for (int c = 0; c < 3 && al->cosine; c++)
        v[c] = wo[2] > SB_HORIZON_Z ? v[c] / wo[2] : 0;
    return reader_add(rd, wi, wo, v, nan, neg);
}

/* ALTA text: "#DIM n m", "#PARAM_IN P" (alta_params), "#PARAM_OUT
 * INV_STERADIAN_COSINE_FACTOR | INV_STERADIAN | RGB_COLOR", "#VS 0", then
 * rows of the n inputs and m values.  *iso: 0 when the rows give pairs at
 * more than one azimuth about the normal (an anisotropic table). */
static sb_result_t read_alta(reader_t *rd, int *iso) {
    alta_t al = {-1, -1, NULL, -1, 0, 0, 0};
    char *line;
    int st;
    sb_result_t r = SB_OK;
    while ((st = sb_lines_next(rd->ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, 0)) continue;
        char *s = sb_trim(line);
        if (s[0] == '#') {
            char *f[4];
            size_t nf = sb_split_fields(s, 0, f, 4);
            r = alta_header(rd, f, nf, &al);
        } else {
            r = alta_row(rd, s, &al);
        }
        if (r != SB_OK) return r;
    }
    if (st < 0) return r;
    if (al.din < 0 || !al.in) return sb_error(rd->ctx, SB_ERR_FORMAT, "%s: no ALTA header (#DIM, #PARAM_IN)", rd->path);
    rd->info->channels = (size_t)al.dout;
    *iso = !al.azimuth_varies;
    return SB_OK;
}

/* sepbrdf CSV (docs/measured.md). */
enum { COL_TI, COL_PI, COL_TO, COL_PO, COL_R, COL_G, COL_B, COL_VALUE, NCOLS };
static const char *const csv_names[NCOLS] = {"theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "value"};

/* CSV state: the metadata (angle unit, symmetry, reciprocity), the
 * header's columns (col[k]: field of column k or -1; unit: radians per
 * unit of an angle column), the row fields, and whether phi_i varies. */
typedef struct csv {
    long col[NCOLS];
    double unit[NCOLS], meta_unit;
    int iso, recip, header;
    size_t ncols;
    char **f;
    double phi_i0;
    int phi_i_varies;
} csv_t;

/* One of the words of `words` (NULL-terminated); its index, or -1. */
static int word_of(const char *val, const char *const *words) {
    for (int k = 0; words[k]; k++)
        if (strcmp(val, words[k]) == 0) return k;
    return -1;
}

/* "# key: value" before the header: units, symmetry, reciprocal; other
 * keys are free comments. */
static sb_result_t csv_meta(reader_t *rd, char *s, csv_t *cv) {
    static const char *const units[] = {"degrees", "deg", "radians", "rad", NULL};
    static const char *const sym[] = {"anisotropic", "isotropic", NULL}, *const yn[] = {"no", "yes", NULL};
    char *colon = strchr(s + 1, ':');
    if (!colon) return SB_OK;
    *colon = 0;
    char *key = sb_trim(s + 1), *val = sb_trim(colon + 1);
    int k;
    if (strcmp(key, "units") == 0) {
        if ((k = word_of(val, units)) < 0)
            return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: units '%.40s' unknown, need degrees or radians", rd->path,
                            rd->lr.line, val);
        cv->meta_unit = k < 2 ? SB_PI / 180 : 1;
    } else if (strcmp(key, "symmetry") == 0) {
        if ((k = word_of(val, sym)) < 0)
            return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: symmetry '%.40s' unknown, need isotropic or anisotropic",
                            rd->path, rd->lr.line, val);
        cv->iso = k;
    } else if (strcmp(key, "reciprocal") == 0) {
        if ((k = word_of(val, yn)) < 0)
            return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: reciprocal '%.40s' unknown, need yes or no", rd->path,
                            rd->lr.line, val);
        cv->recip = k;
    }
    return SB_OK;
}

/* Header field c (f[c]): the column it names, with an optional _deg or
 * _rad unit suffix on angles. */
static sb_result_t csv_column(reader_t *rd, csv_t *cv, size_t c) {
    char name[64];
    double u = 0;
    snprintf(name, sizeof name, "%s", cv->f[c]);
    size_t len = strlen(name);
    if (len > 4 && strcmp(name + len - 4, "_deg") == 0) {
        name[len - 4] = 0;
        u = SB_PI / 180;
    } else if (len > 4 && strcmp(name + len - 4, "_rad") == 0) {
        name[len - 4] = 0;
        u = 1;
    }
    for (int k = 0; k < NCOLS; k++) {
        if (strcmp(name, csv_names[k]) != 0) continue;
        if (cv->col[k] >= 0)
            return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: column '%s' appears twice", rd->path, rd->lr.line,
                            csv_names[k]);
        if (u != 0 && k >= COL_R)
            return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: column '%.40s': only angles take a unit suffix", rd->path,
                            rd->lr.line, cv->f[c]);
        cv->col[k] = (long)c;
        cv->unit[k] = u;
    }
    return SB_OK;
}

/* The header line: count fields, then map names to columns. */
static sb_result_t csv_header(reader_t *rd, char *s, csv_t *cv) {
    sb_context_t *ctx = rd->ctx;
    size_t n = 1;
    for (const char *q = s; *q; q++)
        n += *q == ',';
    if (n > 1024)
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header with %zu columns (at most 1024)", rd->path, rd->lr.line, n);
    cv->f = malloc(n * sizeof *cv->f);
    if (!cv->f) return sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
    cv->ncols = sb_split_fields(s, ',', cv->f, n);
    sb_result_t r;
    for (size_t c = 0; c < cv->ncols; c++)
        if ((r = csv_column(rd, cv, c)) != SB_OK) return r;
    for (int k = 0; k <= COL_PO; k++)
        if (cv->col[k] < 0)
            return sb_error(ctx, SB_ERR_FORMAT,
                            "%s:%zu: header lacks column '%s' (need theta_i, phi_i, theta_o, phi_o and "
                            "r, g, b or value; is the first line a header?)",
                            rd->path, rd->lr.line, csv_names[k]);
    const long *col = cv->col;
    int rgb = col[COL_R] >= 0 && col[COL_G] >= 0 && col[COL_B] >= 0;
    int any_rgb = col[COL_R] >= 0 || col[COL_G] >= 0 || col[COL_B] >= 0;
    if ((any_rgb && !rgb) || (rgb == (col[COL_VALUE] >= 0)))
        return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header needs either r, g, b or value (not both)", rd->path,
                        rd->lr.line);
    rd->info->channels = rgb ? 3 : 1;
    for (int k = 0; k <= COL_PO; k++)
        if (cv->unit[k] == 0) cv->unit[k] = cv->meta_unit;
    cv->header = 1;
    return SB_OK;
}

/* A row: four angles and r, g, b or one value. */
static sb_result_t csv_row(reader_t *rd, char *s, csv_t *cv) {
    size_t n = sb_split_fields(s, ',', cv->f, cv->ncols);
    if (n != cv->ncols)
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %zu fields, the header has %zu", rd->path, rd->lr.line, n,
                        cv->ncols);
    const long *col = cv->col;
    double a[4], v[3];
    int nan = 0;
    sb_result_t r;
    for (int k = 0; k <= COL_PO; k++)
        if ((r = angle_field(rd, csv_names[k], cv->f[col[k]], cv->unit[k], k % 2 ? ANGLE_PHI : ANGLE_THETA, &a[k])) !=
            SB_OK)
            return r;
    if (rd->info->channels == 3) {
        for (int k = 0; k < 3; k++)
            if ((r = value_field(rd, csv_names[COL_R + k], cv->f[col[COL_R + k]], &v[k], &nan)) != SB_OK) return r;
    } else {
        if ((r = value_field(rd, "value", cv->f[col[COL_VALUE]], &v[0], &nan)) != SB_OK) return r;
        v[1] = v[2] = v[0];
    }
    if (isnan(cv->phi_i0))
        cv->phi_i0 = a[1];
    else if (a[1] != cv->phi_i0)
        cv->phi_i_varies = 1;
    double wi[3], wo[3];
    sb_dir_from_angles(a[0], a[1], wi);
    sb_dir_from_angles(a[2], a[3], wo);
    return reader_add(rd, wi, wo, v, nan, v[0] < 0 || v[1] < 0 || v[2] < 0);
}

static sb_result_t read_csv(reader_t *rd, int *iso_out, int *recip_out) {
    csv_t cv = {.meta_unit = SB_PI / 180, .iso = -1, .recip = 1, .phi_i0 = NAN};
    for (int k = 0; k < NCOLS; k++)
        cv.col[k] = -1;
    char *line;
    int st = 0;
    sb_result_t r = SB_OK;
    while (r == SB_OK && (st = sb_lines_next(rd->ctx, &rd->lr, &line, &r)) > 0) {
        char *s = sb_trim(line);
        if (!*s) continue;
        if (s[0] == '#')
            r = cv.header ? SB_OK : csv_meta(rd, s, &cv);
        else
            r = cv.header ? csv_row(rd, s, &cv) : csv_header(rd, s, &cv);
    }
    if (r == SB_OK && st >= 0 && !cv.header)
        r = sb_error(rd->ctx, SB_ERR_FORMAT, "%s: no header line (theta_i,phi_i,theta_o,phi_o,r,g,b)", rd->path);
    if (r == SB_OK) {
        /* Undeclared symmetry: one light azimuth cannot show anisotropy. */
        *iso_out = cv.iso >= 0 ? cv.iso : !cv.phi_i_varies;
        *recip_out = cv.recip;
    }
    free(cv.f);
    return r;
}

typedef enum scattered_kind { KIND_CORNELL, KIND_ALTA, KIND_CSV } scattered_kind_t;

/* The format-specific lines `info` prints for a scattered table. */
static void scattered_fields(sb_measured_info_t *info) {
    sb_info_field(info, "rows", (double)info->rows, "%zu (used %zu; skipped %zu: NaN %zu, at/below horizon %zu)",
                  info->rows, info->samples, info->missing, info->nan_rows, info->horizon_rows);
    sb_info_field(info, "negative", (double)info->negative, "%zu rows (kept)", info->negative);
    sb_info_field(info, "theta max", NAN, "i %.2f deg, o %.2f deg", info->theta_i_max * 180 / SB_PI,
                  info->theta_o_max * 180 / SB_PI);
    sb_info_field(info, "interp", NAN, "%s, k = %zu, radius %.3g deg (median spacing %.3g deg), %zu-D embedding",
                  sb_interp_name(info->interp), info->neighbours, info->radius * 180 / SB_PI,
                  info->spacing * 180 / SB_PI, info->dims);
    const double *cv = info->interp_cv;
    sb_info_field(info, "interp cv", cv[info->interp],
                  "%.3g %% (%s); nearest %.3g %%, linear %.3g %%, idw %.3g %%, quadratic %.3g %% (%zu held out)",
                  100 * cv[info->interp], sb_interp_name(info->interp), 100 * cv[SB_INTERP_NEAREST],
                  100 * cv[SB_INTERP_LINEAR], 100 * cv[SB_INTERP_IDW], 100 * cv[SB_INTERP_QUADRATIC],
                  info->cv_held_out);
}

static sb_result_t scattered_open(sb_context_t *ctx, const char *path, scattered_kind_t kind,
                                  const sb_measured_opts_t *o, sb_source_t **out, sb_measured_info_t *info) {
    sb_result_t r;
    FILE *fp = sb_fopen_regular(ctx, path, "measured table", SB_MEASURED_MAX_FILE, &r);
    if (!fp) return r;
    reader_t rd = {ctx, path, {fp, path, 0, NULL, 0}, {NULL, 0, 0}, info};
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    info->white = o->white;
    info->gamut = o->gamut;
    int iso = 1, recip = 1;
    if (kind == KIND_CORNELL)
        r = read_cornell(&rd, o);
    else if (kind == KIND_ALTA)
        r = read_alta(&rd, &iso);
    else
        r = read_csv(&rd, &iso, &recip);
    free(rd.lr.buf);
    fclose(fp);
    info->samples = rd.ss.n;
    info->missing = info->nan_rows + info->horizon_rows;
    for (int c = 0; c < 3; c++) {
        info->value_mean[c] = rd.ss.n ? info->value_mean[c] / (double)rd.ss.n : 0;
        if (!rd.ss.n) info->value_min[c] = info->value_max[c] = 0;
    }
    if (r == SB_OK) r = sb_table_create_(ctx, path, &rd.ss, iso, recip, o, info, out);
    free(rd.ss.s);
    if (r == SB_OK) scattered_fields(info);
    return r;
}

static sb_result_t open_cornell(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                                sb_measured_info_t *info) {
    return scattered_open(ctx, path, KIND_CORNELL, o, out, info);
}
static sb_result_t open_alta(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                             sb_measured_info_t *info) {
    return scattered_open(ctx, path, KIND_ALTA, o, out, info);
}
static sb_result_t open_csv(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                            sb_measured_info_t *info) {
    return scattered_open(ctx, path, KIND_CSV, o, out, info);
}

/* A line of head[] (not NUL-terminated) starting with `prefix`. */
static int head_has_line(const char *head, size_t n, const char *prefix) {
    size_t m = strlen(prefix);
    for (size_t i = 0; i + m <= n; i++)
        if ((i == 0 || head[i - 1] == '\n') && memcmp(head + i, prefix, m) == 0) return 1;
    return 0;
}

/* Cornell: "# num wls" first (after blanks and a UTF-8 byte order mark). */
static int sniff_cornell(const unsigned char *head, size_t n) {
    const char *h = (const char *)head;
    size_t i = n >= 3 && memcmp(h, "\xef\xbb\xbf", 3) == 0 ? 3 : 0;
    while (i < n && (h[i] == ' ' || h[i] == '\t' || h[i] == '\r' || h[i] == '\n'))
        i++;
    return n - i >= 9 && memcmp(h + i, "# num wls", 9) == 0 ? 2 : 0;
}
static int sniff_alta(const unsigned char *head, size_t n) {
    const char *h = (const char *)head;
    return head_has_line(h, n, "#PARAM_IN") || head_has_line(h, n, "#DIM") ? 2 : 0;
}
/* CSV: a header naming theta_i somewhere (plausible only). */
static int sniff_csv(const unsigned char *head, size_t n) {
    for (size_t k = 0; k + 7 <= n; k++)
        if (memcmp(head + k, "theta_i", 7) == 0) return 1;
    return 0;
}

const sb_reader_t sb_reader_cornell = {"cornell", "Cornell .brdf", ".brdf", sniff_cornell, open_cornell};
const sb_reader_t sb_reader_alta = {"alta", "ALTA", ".alta", sniff_alta, open_alta};
const sb_reader_t sb_reader_csv = {"csv", "sepbrdf CSV", ".csv", sniff_csv, open_csv};
