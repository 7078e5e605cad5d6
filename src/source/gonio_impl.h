/* Private: what the gonioreflectometer table readers share (gonio.c), one
 * file per format (gonio_cornell.c, gonio_alta.c, gonio_csv.c).  A reader
 * reads its rows into an sb_gonio_t; sb_gonio_open_ turns what it read into
 * the interpolated source of scattered samples (scattered.c).  A format that
 * reads like an existing one (a CSV under another name) reuses that reader's
 * read function: one file with its descriptor, one row in measured.c. */
#ifndef SEPBRDF_GONIO_IMPL_H
#define SEPBRDF_GONIO_IMPL_H

#include "source/measured_impl.h"

/* A table being read: the lines, the samples kept so far, what it held. */
typedef struct sb_gonio {
    sb_context_t *ctx;
    const char *path;
    sb_lines_t lr;
    sb_samples_t ss;
    sb_measured_info_t *info;
} sb_gonio_t;

/* Domains of the angles in a row (radians, a rounding slack of 1e-9):
 * an elevation lies in [0, pi] (above pi/2 it is below the horizon: the
 * row is skipped and counted), an azimuth in [-2 pi, 2 pi], an ALTA
 * projection theta_v cos/sin(dphi) in [-pi, pi].  Anything else is not an
 * angle of a direction: refused with the file and line. */
typedef enum sb_angle_kind { SB_ANGLE_THETA, SB_ANGLE_PHI, SB_ANGLE_PROJ } sb_angle_kind_t;

/* One row: classify (NaN, horizon), then keep.  Angles must be finite. */
sb_result_t sb_gonio_add_(sb_gonio_t *rd, const double wi[3], const double wo[3], const double f[3], int nan,
                          int negative);
/* SB_ERR_FORMAT naming the file, the line, `what` and the field. */
sb_result_t sb_gonio_bad_number_(sb_gonio_t *rd, const char *what, const char *field);
sb_result_t sb_gonio_not_finite_(sb_gonio_t *rd, const char *what, const char *field);
/* Parse an angle field (finite, in its domain), times `unit`. */
sb_result_t sb_gonio_angle_(sb_gonio_t *rd, const char *what, const char *s, double unit, sb_angle_kind_t kind,
                            double *out);
/* Parse a value field: NaN marks a missing value (*nan = 1), inf is an error. */
sb_result_t sb_gonio_value_(sb_gonio_t *rd, const char *what, const char *s, double *out, int *nan);
/* Blank, or (comment != 0) a comment line starting with `comment`. */
int sb_gonio_blank_(const char *s, char comment);

/* A format's reading: every line of rd->lr into rd->ss through
 * sb_gonio_add_; *iso and *recip (preset to 1) say which symmetries the
 * table declares or shows. */
typedef sb_result_t (*sb_gonio_read_fn)(sb_gonio_t *rd, const sb_measured_opts_t *o, int *iso, int *recip);

/* Open `path`, read it with `read`, and build the interpolated source
 * (sb_table_create_) and the lines `info` prints: a reader's open(). */
sb_result_t sb_gonio_open_(sb_context_t *ctx, const char *path, sb_gonio_read_fn read, const sb_measured_opts_t *o,
                           sb_source_t **out, sb_measured_info_t *info);

/* The sepbrdf CSV reading (docs/measured.md) and its sniff (a header
 * naming theta_i: plausible only), for aliases of the format. */
sb_result_t sb_gonio_read_csv_(sb_gonio_t *rd, const sb_measured_opts_t *o, int *iso, int *recip);
int sb_gonio_sniff_csv_(const unsigned char *head, size_t n);

#endif
