/* The sepbrdf CSV gonio table (docs/measured.md): the reader. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "source/gonio_impl.h"
#include "util/internal.h"

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
static sb_result_t csv_meta(sb_gonio_t *rd, char *s, csv_t *cv) {
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
static sb_result_t csv_column(sb_gonio_t *rd, csv_t *cv, size_t c) {
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
static sb_result_t csv_header(sb_gonio_t *rd, char *s, csv_t *cv) {
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
static sb_result_t csv_row(sb_gonio_t *rd, char *s, csv_t *cv) {
    size_t n = sb_split_fields(s, ',', cv->f, cv->ncols);
    if (n != cv->ncols)
        return sb_error(rd->ctx, SB_ERR_FORMAT, "%s:%zu: %zu fields, the header has %zu", rd->path, rd->lr.line, n,
                        cv->ncols);
    const long *col = cv->col;
    double a[4], v[3];
    int nan = 0;
    sb_result_t r;
    for (int k = 0; k <= COL_PO; k++)
        if ((r = sb_gonio_angle_(rd, csv_names[k], cv->f[col[k]], cv->unit[k], k % 2 ? SB_ANGLE_PHI : SB_ANGLE_THETA,
                                 &a[k])) != SB_OK)
            return r;
    if (rd->info->channels == 3) {
        for (int k = 0; k < 3; k++)
            if ((r = sb_gonio_value_(rd, csv_names[COL_R + k], cv->f[col[COL_R + k]], &v[k], &nan)) != SB_OK) return r;
    } else {
        if ((r = sb_gonio_value_(rd, "value", cv->f[col[COL_VALUE]], &v[0], &nan)) != SB_OK) return r;
        v[1] = v[2] = v[0];
    }
    if (isnan(cv->phi_i0))
        cv->phi_i0 = a[1];
    else if (a[1] != cv->phi_i0)
        cv->phi_i_varies = 1;
    double wi[3], wo[3];
    sb_dir_from_angles(a[0], a[1], wi);
    sb_dir_from_angles(a[2], a[3], wo);
    return sb_gonio_add_(rd, wi, wo, v, nan, v[0] < 0 || v[1] < 0 || v[2] < 0);
}

sb_result_t sb_gonio_read_csv_(sb_gonio_t *rd, const sb_measured_opts_t *o, int *iso_out, int *recip_out) {
    (void)o;
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

static sb_result_t open_csv(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                            sb_measured_info_t *info) {
    return sb_gonio_open_(ctx, path, sb_gonio_read_csv_, o, out, info);
}

int sb_gonio_sniff_csv_(const unsigned char *head, size_t n) {
    for (size_t k = 0; k + 7 <= n; k++)
        if (memcmp(head + k, "theta_i", 7) == 0) return 1;
    return 0;
}

const sb_reader_t sb_reader_csv = {"csv", "sepbrdf CSV", ".csv", sb_gonio_sniff_csv_, open_csv};
