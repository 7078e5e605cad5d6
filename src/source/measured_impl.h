/* Private: shared by the measured-data modules (measured.c, merl.c,
 * rgl.c, gonio.c, gonio_sim.c, scattered*.c, spectral.c). */
#ifndef SEPBRDF_MEASURED_IMPL_H
#define SEPBRDF_MEASURED_IMPL_H

#include <stdio.h>

#include "sepbrdf/measured.h"

/* A direction with z below this (theta >= pi/2 - 1e-9) is at or below the
 * horizon: f_r is not defined there, and text tables round angles. */
#define SB_HORIZON_Z 1e-9
/* The largest measured file read (bytes); every reader opens its file
 * with sb_fopen_regular, so devices and FIFOs are refused. */
#define SB_MEASURED_MAX_FILE (16ull << 30)

/* Open a measured table file: the entry point source.c calls for a path. */
sb_result_t sb_measured_open_hook(sb_context_t *ctx, const char *path, sb_source_t **out);

/* Longest accepted text line (bytes): a Cornell row of 4096 wavelengths at
 * 24 characters a number fits; anything longer is hostile. */
#define SB_LINE_MAX ((size_t)1 << 20)

/* Line reader over a text file: lines end with LF, CR LF or CR alone; a
 * UTF-8 byte order mark before the first line is dropped; counts lines,
 * refuses NUL bytes and lines longer than SB_LINE_MAX. */
typedef struct sb_lines {
    FILE *fp;
    const char *path;
    size_t line; /* 1-based number of the line last returned */
    char *buf;
    size_t cap;
} sb_lines_t;

/* 1: *out is the next line; 0: end of file; < 0: error reported via ctx
 * (*err receives the code). */
int sb_lines_next(sb_context_t *ctx, sb_lines_t *lr, char **out, sb_result_t *err);

/* Split s in place into fields: sep = 0 splits on blanks (runs of spaces
 * and tabs), sep = ',' on commas (fields trimmed).  Stores at most `max`
 * pointers; returns the number of fields. */
size_t sb_split_fields(char *s, char sep, char **fields, size_t max);
/* A complete number (strtod syntax, "nan" and "inf" included); 0 on success. */
int sb_parse_number(const char *s, double *out);
char *sb_trim(char *s);

/* Half vector angle theta_h and difference vector d of a pair (see
 * sb_half_diff_angles); 0 when wi = -wo. */
int sb_half_diff_vec_(const double wi[3], const double wo[3], double *theta_h, double d[3]);

/* Keep a copy of what a table held with its source (sb_measured_source_info);
 * -1 when out of memory. */
int sb_source_set_measured_(sb_source_t *src, const sb_measured_info_t *info);

/* Give a source the tables a layout is built on (owned by it from then;
 * sets SB_SOURCE_TABLES; NULL takes them away). */
void sb_source_set_tables_(sb_source_t *src, sb_layout_tables_t *tables);

/* Give a table source its samples (sb_source_sample_count, sb_source_sample). */
void sb_source_set_samples_(sb_source_t *src, size_t (*count)(const void *self),
                            int (*sample)(const void *self, size_t k, double wi[3], double wo[3], double f[3]));

/* Scattered samples as the text readers collect them: wi[3], wo[3], f[3]
 * (RGB f_r) per sample, both directions above the horizon. */
#define SB_SAMPLE_DOUBLES 9
#define SB_MAX_ROWS ((size_t)1 << 31)
typedef struct sb_samples {
    double *s;
    size_t n, cap;
} sb_samples_t;

/* Append a sample (value statistics of info updated); SB_ERR_OVERFLOW past
 * SB_MAX_ROWS or the memory limit. */
sb_result_t sb_samples_push_(sb_context_t *ctx, const char *path, sb_samples_t *ss, const double wi[3],
                             const double wo[3], const double f[3], sb_measured_info_t *info);
/* The interpolated source of scattered samples (scattered.c): embedding,
 * k-d tree, interpolation per o->interp; fills the interpolation fields of
 * info. */
sb_result_t sb_table_create_(sb_context_t *ctx, const char *path, sb_samples_t *ss, int iso, int recip,
                             const sb_measured_opts_t *o, sb_measured_info_t *info, sb_source_t **out);

/* A measured format (sb_measured_reader_t, measured.h): one descriptor
 * `const sb_reader_t sb_reader_<name>` in the reader's own file plus one
 * row in the registry's list (SB_READERS in measured.c). */
typedef sb_measured_reader_t sb_reader_t;

/* Append a format-specific field (number: NAN when the value is text);
 * silently ignored beyond SB_MEASURED_FIELDS_MAX. */
void sb_info_field(sb_measured_info_t *info, const char *key, double number, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

/* Path of the temporary file written before the rename: PATH.tmp-PID. */
int sb_tmp_name(const char *path, char *buf, size_t size);

#endif
