/* Scattered gonioreflectometer tables (Cornell .brdf, ALTA, sepbrdf CSV):
 * the text readers, and the simulated gonioreflectometer.  The samples
 * they read become an interpolated source in scattered.c. */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "source/measured_impl.h"
#include "util/internal.h"
#include "util/rng.h"

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

/* Cornell / pbrt .brdf: count, wavelengths (may span lines), then rows of
 * 4 + n numbers.  Lines starting with '#' are comments. */
static sb_result_t read_cornell(reader_t *rd, const sb_measured_opts_t *o) {
    sb_context_t *ctx = rd->ctx;
    size_t n = 0, have = 0;
    double *wl = NULL, *w = NULL, *vals = NULL;
    char **fields = NULL;
    sb_result_t r = SB_OK;
    char *line;
    int st, state = 0;
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, '#')) continue;
        if (state == 0) { /* the wavelength count */
            char *f[2];
            size_t nf = sb_split_fields(line, 0, f, 2);
            double v;
            if (nf != 1 || sb_parse_number(f[0], &v) != 0 || !(v >= 1 && v <= MAX_WAVELENGTHS) || v != floor(v)) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength count '%.40s' is not an integer in 1..%d",
                             rd->path, rd->lr.line, nf ? f[0] : "", MAX_WAVELENGTHS);
                goto done;
            }
            n = (size_t)v;
            wl = malloc(n * sizeof *wl);
            w = malloc(3 * n * sizeof *w);
            vals = malloc(n * sizeof *vals);
            fields = malloc((n + 5) * sizeof *fields);
            if (!wl || !w || !vals || !fields) {
                r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
                goto done;
            }
            state = 1;
        } else if (state == 1) { /* wavelengths */
            size_t nf = sb_split_fields(line, 0, fields, n + 5);
            if (have + nf > n) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: more wavelengths than the %zu announced", rd->path,
                             rd->lr.line, n);
                goto done;
            }
            for (size_t k = 0; k < nf; k++) {
                if (sb_parse_number(fields[k], &wl[have]) != 0) {
                    r = bad_number(rd, "wavelength", fields[k]);
                    goto done;
                }
                if (!isfinite(wl[have]) || wl[have] <= 0) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelength '%.40s' is not a positive number", rd->path,
                                 rd->lr.line, fields[k]);
                    goto done;
                }
                if (have > 0 && !(wl[have] > wl[have - 1])) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths not increasing (%g nm after %g nm)", rd->path,
                                 rd->lr.line, wl[have], wl[have - 1]);
                    goto done;
                }
                have++;
            }
            if (have == n) {
                if (wl[n - 1] < 380 || wl[0] > 780) {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: wavelengths %g..%g nm miss the visible range 380..780 nm",
                                 rd->path, rd->lr.line, wl[0], wl[n - 1]);
                    goto done;
                }
                if ((r = sb_spectral_weights(ctx, wl, n, o->white, w)) != SB_OK) goto done;
                rd->info->wavelengths = n;
                rd->info->channels = n;
                rd->info->wl_min = wl[0];
                rd->info->wl_max = wl[n - 1];
                state = 2;
            }
        } else { /* rows */
            size_t nf = sb_split_fields(line, 0, fields, n + 5);
            if (nf != 4 + n) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (4 angles + %zu spectral values)",
                             rd->path, rd->lr.line, nf, 4 + n, n);
                goto done;
            }
            static const char *const an[4] = {"theta_i", "phi_i", "theta_s", "phi_s"};
            double a[4];
            for (int k = 0; k < 4; k++)
                if ((r = angle_field(rd, an[k], fields[k], 1, k % 2 ? ANGLE_PHI : ANGLE_THETA, &a[k])) != SB_OK)
                    goto done;
            int nan = 0;
            for (size_t k = 0; k < n; k++)
                if ((r = value_field(rd, "spectral value", fields[4 + k], &vals[k], &nan)) != SB_OK) goto done;
            double wi[3], wo[3], f[3] = {0, 0, 0};
            sb_dir_from_angles(a[0], a[1], wi);
            sb_dir_from_angles(a[2], a[3], wo);
            int neg = 0;
            for (size_t k = 0; k < n && !nan; k++)
                neg |= vals[k] < 0;
            for (int c = 0; c < 3 && !nan; c++)
                for (size_t k = 0; k < n; k++)
                    f[c] += w[(size_t)c * n + k] * vals[k];
            if ((r = reader_add(rd, wi, wo, f, nan, neg)) != SB_OK) goto done;
        }
    }
    if (st < 0) goto done;
    if (state < 2)
        r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: ends before the %s", rd->path, rd->lr.line,
                     state == 0 ? "wavelength count" : "last wavelength");
done:
    free(wl);
    free(w);
    free(vals);
    free(fields);
    return r;
}

/* ALTA text: "#DIM 3 m", "#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI", "#PARAM_OUT
 * INV_STERADIAN_COSINE_FACTOR | INV_STERADIAN | RGB_COLOR", "#VS 0", then
 * rows theta_l, theta_v cos(dphi), theta_v sin(dphi), m values. */
static sb_result_t read_alta(reader_t *rd) {
    sb_context_t *ctx = rd->ctx;
    long din = -1, dout = -1;
    int have_in = 0, cosine = -1;
    char *line;
    int st;
    sb_result_t r = SB_OK;
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        if (is_blank_or_comment(line, 0)) continue;
        char *s = sb_trim(line);
        if (s[0] == '#') {
            char *f[4];
            size_t nf = sb_split_fields(s, 0, f, 4);
            if (strcmp(f[0], "#DIM") == 0) {
                char *e1 = NULL, *e2 = NULL;
                if (nf == 3) {
                    din = strtol(f[1], &e1, 10);
                    dout = strtol(f[2], &e2, 10);
                }
                if (nf != 3 || *e1 || *e2)
                    return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: #DIM needs two integers", rd->path, rd->lr.line);
                if (din != 3 || (dout != 1 && dout != 3))
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #DIM %ld %ld not supported; need 3 inputs "
                                    "(ISOTROPIC_TL_TV_PROJ_DPHI) and 1 or 3 outputs",
                                    rd->path, rd->lr.line, din, dout);
            } else if (strcmp(f[0], "#PARAM_IN") == 0) {
                if (nf < 2 || strcmp(f[1], "ISOTROPIC_TL_TV_PROJ_DPHI") != 0)
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #PARAM_IN %s not supported; need ISOTROPIC_TL_TV_PROJ_DPHI", rd->path,
                                    rd->lr.line, nf >= 2 ? f[1] : "(none)");
                have_in = 1;
            } else if (strcmp(f[0], "#PARAM_OUT") == 0) {
                if (nf >= 2 && strcmp(f[1], "INV_STERADIAN_COSINE_FACTOR") == 0)
                    cosine = 1;
                else if (nf >= 2 && (strcmp(f[1], "INV_STERADIAN") == 0 || strcmp(f[1], "RGB_COLOR") == 0))
                    cosine = 0;
                else
                    return sb_error(ctx, SB_ERR_UNSUPPORTED,
                                    "%s:%zu: ALTA #PARAM_OUT %s not supported; need INV_STERADIAN_COSINE_FACTOR, "
                                    "INV_STERADIAN or RGB_COLOR",
                                    rd->path, rd->lr.line, nf >= 2 ? f[1] : "(none)");
            } else if (strcmp(f[0], "#VS") == 0) {
                if (nf != 2 || strcmp(f[1], "0") != 0)
                    return sb_error(ctx, SB_ERR_UNSUPPORTED, "%s:%zu: ALTA confidence columns (#VS %s) not supported",
                                    rd->path, rd->lr.line, nf >= 2 ? f[1] : "");
            }
            continue; /* other comments: #SAMPLE, #ORIGIN, #URL, ... */
        }
        if (din < 0 || !have_in || cosine < 0)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: data before the ALTA header (#DIM, #PARAM_IN, #PARAM_OUT)",
                            rd->path, rd->lr.line);
        char *f[8];
        size_t nf = sb_split_fields(s, 0, f, 8), want = 3 + (size_t)dout;
        if (nf != want)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu numbers, expected %zu (3 angles + %ld values)", rd->path,
                            rd->lr.line, nf, want, dout);
        double a[3], v[3];
        static const char *const an[3] = {"theta_l", "theta_v cos(dphi)", "theta_v sin(dphi)"};
        for (int k = 0; k < 3; k++)
            if ((r = angle_field(rd, an[k], f[k], 1, k ? ANGLE_PROJ : ANGLE_THETA, &a[k])) != SB_OK) return r;
        if (hypot(a[1], a[2]) > SB_PI + 1e-9)
            return sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: theta_v = |(%s, %s)| = %g deg is outside 0..180 deg", rd->path,
                            rd->lr.line, f[1], f[2], hypot(a[1], a[2]) * 180 / SB_PI);
        int nan = 0;
        for (long k = 0; k < dout; k++)
            if ((r = value_field(rd, "value", f[3 + k], &v[k], &nan)) != SB_OK) return r;
        if (dout == 1) v[1] = v[2] = v[0];
        double wi[3], wo[3];
        sb_dir_from_angles(a[0], 0, wi);
        sb_dir_from_angles(hypot(a[1], a[2]), atan2(a[2], a[1]), wo);
        /* INV_STERADIAN_COSINE_FACTOR: the value is f_r cos(theta_v) */
        int neg = v[0] < 0 || v[1] < 0 || v[2] < 0;
        for (int c = 0; c < 3 && cosine; c++)
            v[c] = wo[2] > SB_HORIZON_Z ? v[c] / wo[2] : 0;
        if ((r = reader_add(rd, wi, wo, v, nan, neg)) != SB_OK) return r;
    }
    if (st < 0) return r;
    if (din < 0 || !have_in) return sb_error(ctx, SB_ERR_FORMAT, "%s: no ALTA header (#DIM, #PARAM_IN)", rd->path);
    rd->info->channels = (size_t)dout;
    return SB_OK;
}

/* sepbrdf CSV (docs/measured.md). */
enum { COL_TI, COL_PI, COL_TO, COL_PO, COL_R, COL_G, COL_B, COL_VALUE, NCOLS };

static sb_result_t read_csv(reader_t *rd, int *iso_out, int *recip_out) {
    sb_context_t *ctx = rd->ctx;
    static const char *const names[NCOLS] = {"theta_i", "phi_i", "theta_o", "phi_o", "r", "g", "b", "value"};
    long col[NCOLS];
    double unit[NCOLS], meta_unit = SB_PI / 180;
    int iso = -1, recip = 1, header = 0;
    size_t ncols = 0;
    char **f = NULL;
    char *line;
    int st;
    double phi_i0 = NAN;
    int phi_i_varies = 0;
    sb_result_t r = SB_OK;
    for (int k = 0; k < NCOLS; k++) {
        col[k] = -1;
        unit[k] = 0;
    }
    while ((st = sb_lines_next(ctx, &rd->lr, &line, &r)) > 0) {
        char *s = sb_trim(line);
        if (!*s) continue;
        if (s[0] == '#') {
            if (header) continue;
            char *colon = strchr(s + 1, ':');
            if (!colon) continue;
            *colon = 0;
            char *key = sb_trim(s + 1), *val = sb_trim(colon + 1);
            if (strcmp(key, "units") == 0) {
                if (strcmp(val, "degrees") == 0 || strcmp(val, "deg") == 0)
                    meta_unit = SB_PI / 180;
                else if (strcmp(val, "radians") == 0 || strcmp(val, "rad") == 0)
                    meta_unit = 1;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: units '%.40s' unknown, need degrees or radians", rd->path,
                                 rd->lr.line, val);
                    goto done;
                }
            } else if (strcmp(key, "symmetry") == 0) {
                if (strcmp(val, "isotropic") == 0)
                    iso = 1;
                else if (strcmp(val, "anisotropic") == 0)
                    iso = 0;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: symmetry '%.40s' unknown, need isotropic or anisotropic",
                                 rd->path, rd->lr.line, val);
                    goto done;
                }
            } else if (strcmp(key, "reciprocal") == 0) {
                if (strcmp(val, "yes") == 0)
                    recip = 1;
                else if (strcmp(val, "no") == 0)
                    recip = 0;
                else {
                    r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: reciprocal '%.40s' unknown, need yes or no", rd->path,
                                 rd->lr.line, val);
                    goto done;
                }
            }
            continue; /* other keys: free comments */
        }
        if (!header) {
            /* The header: count fields, then map names. */
            size_t n = 1;
            for (const char *q = s; *q; q++)
                n += *q == ',';
            if (n > 1024) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header with %zu columns (at most 1024)", rd->path,
                             rd->lr.line, n);
                goto done;
            }
            f = malloc(n * sizeof *f);
            if (!f) {
                r = sb_error(ctx, SB_ERR_NOMEM, "%s: out of memory", rd->path);
                goto done;
            }
            ncols = sb_split_fields(s, ',', f, n);
            for (size_t c = 0; c < ncols; c++) {
                char name[64];
                double u = 0;
                snprintf(name, sizeof name, "%s", f[c]);
                size_t len = strlen(name);
                if (len > 4 && strcmp(name + len - 4, "_deg") == 0) {
                    name[len - 4] = 0;
                    u = SB_PI / 180;
                } else if (len > 4 && strcmp(name + len - 4, "_rad") == 0) {
                    name[len - 4] = 0;
                    u = 1;
                }
                for (int k = 0; k < NCOLS; k++)
                    if (strcmp(name, names[k]) == 0) {
                        if (col[k] >= 0) {
                            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: column '%s' appears twice", rd->path, rd->lr.line,
                                         names[k]);
                            goto done;
                        }
                        if (u != 0 && k >= COL_R) {
                            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: column '%.40s': only angles take a unit suffix",
                                         rd->path, rd->lr.line, f[c]);
                            goto done;
                        }
                        col[k] = (long)c;
                        unit[k] = u;
                    }
            }
            for (int k = 0; k <= COL_PO; k++)
                if (col[k] < 0) {
                    r = sb_error(ctx, SB_ERR_FORMAT,
                                 "%s:%zu: header lacks column '%s' (need theta_i, phi_i, theta_o, phi_o and "
                                 "r, g, b or value; is the first line a header?)",
                                 rd->path, rd->lr.line, names[k]);
                    goto done;
                }
            int rgb = col[COL_R] >= 0 && col[COL_G] >= 0 && col[COL_B] >= 0;
            int any_rgb = col[COL_R] >= 0 || col[COL_G] >= 0 || col[COL_B] >= 0;
            if ((any_rgb && !rgb) || (rgb == (col[COL_VALUE] >= 0))) {
                r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: header needs either r, g, b or value (not both)", rd->path,
                             rd->lr.line);
                goto done;
            }
            rd->info->channels = rgb ? 3 : 1;
            for (int k = 0; k <= COL_PO; k++)
                if (unit[k] == 0) unit[k] = meta_unit;
            header = 1;
            continue;
        }
        /* A row. */
        size_t n = sb_split_fields(s, ',', f, ncols);
        if (n != ncols) {
            r = sb_error(ctx, SB_ERR_FORMAT, "%s:%zu: %zu fields, the header has %zu", rd->path, rd->lr.line, n, ncols);
            goto done;
        }
        double a[4], v[3];
        int nan = 0;
        for (int k = 0; k <= COL_PO; k++)
            if ((r = angle_field(rd, names[k], f[col[k]], unit[k], k % 2 ? ANGLE_PHI : ANGLE_THETA, &a[k])) != SB_OK)
                goto done;
        if (rd->info->channels == 3) {
            for (int k = 0; k < 3; k++)
                if ((r = value_field(rd, names[COL_R + k], f[col[COL_R + k]], &v[k], &nan)) != SB_OK) goto done;
        } else {
            if ((r = value_field(rd, "value", f[col[COL_VALUE]], &v[0], &nan)) != SB_OK) goto done;
            v[1] = v[2] = v[0];
        }
        if (isnan(phi_i0))
            phi_i0 = a[1];
        else if (a[1] != phi_i0)
            phi_i_varies = 1;
        double wi[3], wo[3];
        sb_dir_from_angles(a[0], a[1], wi);
        sb_dir_from_angles(a[2], a[3], wo);
        if ((r = reader_add(rd, wi, wo, v, nan, v[0] < 0 || v[1] < 0 || v[2] < 0)) != SB_OK) goto done;
    }
    if (st < 0) goto done;
    if (!header) {
        r = sb_error(ctx, SB_ERR_FORMAT, "%s: no header line (theta_i,phi_i,theta_o,phi_o,r,g,b)", rd->path);
        goto done;
    }
    /* Undeclared symmetry: one light azimuth cannot show anisotropy. */
    *iso_out = iso >= 0 ? iso : !phi_i_varies;
    *recip_out = recip;
done:
    free(f);
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
    FILE *fp = fopen(path, "rb");
    if (!fp) return sb_error(ctx, SB_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    reader_t rd = {ctx, path, {fp, path, 0, NULL, 0}, {NULL, 0, 0}, info};
    for (int c = 0; c < 3; c++) {
        info->value_min[c] = INFINITY;
        info->value_max[c] = -INFINITY;
    }
    info->white = o->white;
    info->gamut = o->gamut;
    int iso = 1, recip = 1;
    sb_result_t r;
    if (kind == KIND_CORNELL)
        r = read_cornell(&rd, o);
    else if (kind == KIND_ALTA)
        r = read_alta(&rd);
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

/* ---- simulated gonioreflectometer ------------------------------------- */

/* Standard normal by Box-Muller, one value per call (the pair's second
 * value is kept for the next call). */
typedef struct gauss {
    uint64_t s;
    int have;
    double next;
} gauss_t;

static double gauss_next(gauss_t *g) {
    if (g->have) {
        g->have = 0;
        return g->next;
    }
    double two[2];
    sb_splitmix_gauss2(&g->s, two); /* splitmix64: small, deterministic, good enough for test noise */
    g->next = two[1];
    g->have = 1;
    return two[0];
}

/* The metadata and column lines every table written here ends its header with. */
static void csv_header(FILE *fp, const sb_source_t *src) {
    unsigned flags = sb_source_flags(src);
    fprintf(fp,
            "# units: degrees\n"
            "# symmetry: %s\n"
            "# reciprocal: %s\n"
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n",
            flags & SB_SOURCE_ISOTROPIC ? "isotropic" : "anisotropic", flags & SB_SOURCE_RECIPROCAL ? "yes" : "no");
}

sb_result_t sb_measured_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, size_t *rows) {
    if (!fp || !src) return sb_error(ctx, SB_ERR_ARG, "csv: missing output or source");
    size_t n = sb_source_sample_count(src), written = 0;
    if (n == 0) return sb_error(ctx, SB_ERR_ARG, "csv: %s has no measured samples", sb_source_description(src));
    fprintf(fp, "# sepbrdf table of measured samples (docs/measured.md)\n# source: %s\n", sb_source_description(src));
    csv_header(fp, src);
    for (size_t k = 0; k < n; k++) {
        double wi[3], wo[3], f[3];
        if (!sb_source_sample(src, k, wi, wo, f)) continue;
        double a[4] = {atan2(hypot(wi[0], wi[1]), wi[2]), atan2(wi[1], wi[0]), atan2(hypot(wo[0], wo[1]), wo[2]),
                       atan2(wo[1], wo[0])};
        fprintf(fp, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", a[0] * 180 / SB_PI, a[1] * 180 / SB_PI,
                a[2] * 180 / SB_PI, a[3] * 180 / SB_PI, f[0], f[1], f[2]);
        written++;
    }
    if (rows) *rows = written;
    if (ferror(fp)) return sb_error(ctx, SB_ERR_IO, "csv: write error: %s", strerror(errno));
    return SB_OK;
}

sb_result_t sb_gonio_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, const sb_gonio_opts_t *opts,
                               size_t *rows) {
    if (!fp || !src) return sb_error(ctx, SB_ERR_ARG, "gonio: missing output or source");
    sb_gonio_opts_t o = {0};
    if (opts) o = *opts;
    if (!o.n_theta_i && !o.n_phi_i && !o.n_theta_o && !o.n_phi_o) {
        o.n_theta_i = 18;
        o.n_phi_i = 1;
        o.n_theta_o = 18;
        o.n_phi_o = 72;
    }
    size_t nn[4] = {o.n_theta_i, o.n_phi_i, o.n_theta_o, o.n_phi_o}, total = 1;
    static const char *const nm[4] = {"N_theta_i", "N_phi_i", "N_theta_o", "N_phi_o"};
    for (int k = 0; k < 4; k++) {
        if (nn[k] < 1 || nn[k] > 4096)
            return sb_error(ctx, SB_ERR_RANGE, "gonio: %s = %zu out of range, need 1..4096", nm[k], nn[k]);
        if (sb_size_mul(total, nn[k], &total) || total > SB_MAX_ROWS)
            return sb_error(ctx, SB_ERR_OVERFLOW, "gonio: %zu x %zu x %zu x %zu positions exceed %zu rows", nn[0],
                            nn[1], nn[2], nn[3], SB_MAX_ROWS);
    }
    if (!(o.noise >= 0 && o.noise <= 10))
        return sb_error(ctx, SB_ERR_RANGE, "gonio: noise %g out of range, need 0..10", o.noise);
    gauss_t g = {o.seed ? o.seed : 1, 0, 0};
    fprintf(fp,
            "# sepbrdf gonio table (docs/measured.md)\n"
            "# source: %s\n"
            "# gonio: %zu,%zu,%zu,%zu (theta_k = (k + 1/2) 90/N deg, phi_k = k 360/N deg)\n"
            "# noise: %.17g (multiplicative gaussian, seed %llu)\n",
            sb_source_description(src), nn[0], nn[1], nn[2], nn[3], o.noise, (unsigned long long)(o.seed ? o.seed : 1));
    csv_header(fp, src);
    size_t written = 0;
    for (size_t a = 0; a < nn[0]; a++)
        for (size_t b = 0; b < nn[1]; b++)
            for (size_t c = 0; c < nn[2]; c++)
                for (size_t d = 0; d < nn[3]; d++) {
                    double ti = ((double)a + 0.5) * 90 / (double)nn[0], pi_ = (double)b * 360 / (double)nn[1];
                    double to = ((double)c + 0.5) * 90 / (double)nn[2], po = (double)d * 360 / (double)nn[3];
                    double wi[3], wo[3], v[3];
                    sb_dir_from_angles(ti * SB_PI / 180, pi_ * SB_PI / 180, wi);
                    sb_dir_from_angles(to * SB_PI / 180, po * SB_PI / 180, wo);
                    if (!sb_source_eval(src, wi, wo, v) || !isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
                        continue;
                    if (o.noise > 0)
                        for (int k = 0; k < 3; k++)
                            v[k] *= 1 + o.noise * gauss_next(&g);
                    fprintf(fp, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", ti, pi_, to, po, v[0], v[1], v[2]);
                    written++;
                }
    if (rows) *rows = written;
    if (ferror(fp)) return sb_error(ctx, SB_ERR_IO, "gonio: write error: %s", strerror(errno));
    return SB_OK;
}
