/* ALTA text tables (measured.h): the reader. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "source/gonio_impl.h"
#include "util/internal.h"

/* ALTA input parameterisations (ALTA's params.h names; angles in
 * radians, l the light = incoming direction wi, v the view = outgoing
 * wo): the row's din inputs, their kinds, whether a pair's absolute
 * azimuth is given (the table may be anisotropic), and the directions. */
typedef struct alta_param {
    const char *name;
    int din;
    const char *what[6];
    sb_angle_kind_t kind[6]; /* SB_ANGLE_NONE: a Cartesian component */
    int azimuth;             /* the pair's azimuth about the normal is in the row */
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

#define SB_ANGLE_NONE ((sb_angle_kind_t)-1)
static const alta_param_t alta_params[] = {
    {"ISOTROPIC_TL_TV_PROJ_DPHI",
     3,
     {"theta_l", "theta_v cos(dphi)", "theta_v sin(dphi)"},
     {SB_ANGLE_THETA, SB_ANGLE_PROJ, SB_ANGLE_PROJ},
     0,
     alta_proj},
    {"ISOTROPIC_TV_TL_DPHI",
     3,
     {"theta_v", "theta_l", "dphi"},
     {SB_ANGLE_THETA, SB_ANGLE_THETA, SB_ANGLE_PHI},
     0,
     alta_tv_tl},
    {"RUSIN_TH_TD_PD",
     3,
     {"theta_h", "theta_d", "phi_d"},
     {SB_ANGLE_THETA, SB_ANGLE_THETA, SB_ANGLE_PHI},
     0,
     alta_rusin3},
    {"RUSIN_TH_PH_TD_PD",
     4,
     {"theta_h", "phi_h", "theta_d", "phi_d"},
     {SB_ANGLE_THETA, SB_ANGLE_PHI, SB_ANGLE_THETA, SB_ANGLE_PHI},
     1,
     alta_rusin4},
    {"SPHERICAL_TL_PL_TV_PV",
     4,
     {"theta_l", "phi_l", "theta_v", "phi_v"},
     {SB_ANGLE_THETA, SB_ANGLE_PHI, SB_ANGLE_THETA, SB_ANGLE_PHI},
     1,
     alta_spherical},
    {"CARTESIAN",
     6,
     {"l_x", "l_y", "l_z", "v_x", "v_y", "v_z"},
     {SB_ANGLE_NONE, SB_ANGLE_NONE, SB_ANGLE_NONE, SB_ANGLE_NONE, SB_ANGLE_NONE, SB_ANGLE_NONE},
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
static sb_result_t alta_dims(sb_gonio_t *rd, const alta_t *al) {
    if (al->din < 0 || !al->in || al->din == al->in->din) return SB_OK;
    return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: #PARAM_IN %s has %d inputs, #DIM says %ld", rd->path, rd->lr.line,
                    al->in->name, al->in->din, al->din);
}

/* A '#' line of the header (fields f, nf of them): checks what sepbrdf
 * reads; other comments (#SAMPLE, #ORIGIN, #URL, ...) pass. */
static sb_result_t alta_header(sb_gonio_t *rd, char **f, size_t nf, alta_t *al) {
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
static sb_result_t alta_row(sb_gonio_t *rd, char *s, alta_t *al) {
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
        if (pa->kind[k] != SB_ANGLE_NONE) {
            if ((r = sb_gonio_angle_(rd, pa->what[k], f[k], 1, pa->kind[k], &a[k])) != SB_OK) return r;
        } else if (sb_parse_number(f[k], &a[k]) != 0) {
            return sb_gonio_bad_number_(rd, pa->what[k], f[k]);
        } else if (!isfinite(a[k])) {
            return sb_gonio_not_finite_(rd, pa->what[k], f[k]);
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
        if ((r = sb_gonio_value_(rd, "value", f[pa->din + k], &v[k], &nan)) != SB_OK) return r;
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
    return sb_gonio_add_(rd, wi, wo, v, nan, neg);
}

/* ALTA text: "#DIM n m", "#PARAM_IN P" (alta_params), "#PARAM_OUT
 * INV_STERADIAN_COSINE_FACTOR | INV_STERADIAN | RGB_COLOR", "#VS 0", then
 * rows of the n inputs and m values.  *iso: 0 when the rows give pairs at
 * more than one azimuth about the normal (an anisotropic table). */
static sb_result_t read_alta(sb_gonio_t *rd, const sb_measured_opts_t *o, int *iso, int *recip) {
    (void)o, (void)recip; /* reciprocal */
    alta_t al = {-1, -1, NULL, -1, 0, 0, 0};
    char *line;
    int st;
    sb_result_t r = SB_OK;
    while ((st = sb_lines_next(rd->ctx, &rd->lr, &line, &r)) > 0) {
        if (sb_gonio_blank_(line, 0)) continue;
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

static sb_result_t open_alta(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                             sb_measured_info_t *info) {
    return sb_gonio_open_(ctx, path, read_alta, o, out, info);
}

/* A line of head[] (not NUL-terminated) starting with `prefix`. */
static int head_has_line(const char *head, size_t n, const char *prefix) {
    size_t m = strlen(prefix);
    for (size_t i = 0; i + m <= n; i++)
        if ((i == 0 || head[i - 1] == '\n') && memcmp(head + i, prefix, m) == 0) return 1;
    return 0;
}
static int sniff_alta(const unsigned char *head, size_t n) {
    const char *h = (const char *)head;
    return head_has_line(h, n, "#PARAM_IN") || head_has_line(h, n, "#DIM") ? 2 : 0;
}

const sb_reader_t sb_reader_alta = {"alta", "ALTA", ".alta", sniff_alta, open_alta};
