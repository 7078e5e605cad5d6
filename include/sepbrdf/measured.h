/* sepbrdf: measured BRDF tables behind the source interface.
 *
 * Formats (detected from the content, then the file name extension):
 *   MERL      .binary: three little-endian int32 dims 90, 90, 180, then
 *             3 x 1,458,000 little-endian float64, channel-planar R, G, B,
 *             scaled by R 1/1500, G 1.15/1500, B 1.66/1500.  Cell
 *             index = i_phi_d + 180 (i_theta_d + 90 i_theta_h) with
 *               i_theta_h = floor(90 sqrt(theta_h / (pi/2)))  (clamped 0..89)
 *               i_theta_d = floor(90 theta_d / (pi/2))         (clamped 0..89)
 *               i_phi_d   = floor(180 phi_d / pi)              (clamped 0..179)
 *             after folding phi_d into [0, pi) (phi_d >= pi -> phi_d - pi,
 *             reciprocity).  Negative (and NaN) cells are missing.
 *   Cornell   pbrt/Cornell spectral .brdf text: "# num wls", the count,
 *             "# wls", the wavelengths (nm), then rows theta_i phi_i
 *             theta_s phi_s v_1 .. v_n (radians, f_r in 1/sr per wavelength),
 *             converted to linear sRGB (see "Spectra" below).
 *   ALTA      text with "#DIM 3 1" (or "#DIM 3 3"), "#PARAM_IN
 *             ISOTROPIC_TL_TV_PROJ_DPHI" and "#PARAM_OUT
 *             INV_STERADIAN_COSINE_FACTOR" (value = f_r cos theta_v) or
 *             "INV_STERADIAN" (value = f_r); rows theta_l,
 *             theta_v cos(dphi), theta_v sin(dphi), value(s).
 *   RGL       the RGL material database's Mitsuba tensor_file (.bsdf):
 *             VNDF-warped tables per incident slice, evaluated as Mitsuba
 *             3's `measured` plugin does; isotropic
 *             or anisotropic (symmetry reductions 1, 2, 4), RGB or spectral.
 *   CSV       the sepbrdf gonio table (docs/measured.md): comment lines
 *             "# key: value" (units, symmetry, reciprocal), a header naming
 *             the columns theta_i, phi_i, theta_o, phi_o (suffix _deg or
 *             _rad optional) and r, g, b or value, then one row per sample.
 *
 * Directions follow source.h: local frame, z = normal, wi towards the light
 * (l), wo towards the viewer (v).  A measured source returns 0 (missing) for
 * pairs with a direction at or below the horizon and for pairs the table
 * does not cover; sb_matrix_build() masks those cells.  The factorisation
 * excludes masked cells from the fit (the masked solver, solver.h) and from
 * the error report, unless asked to factor them as zeros (zero_fill in
 * factor.h); see docs/measured.md.
 *
 * Scattered tables (Cornell, ALTA, CSV) are interpolated: see
 * sb_measured_opts_t.  All sources are read-only after opening, so eval is
 * thread-safe. */
#ifndef SEPBRDF_MEASURED_H
#define SEPBRDF_MEASURED_H

#include <stdio.h>

#include "common.h"
#include "matrix.h"
#include "param.h"
#include "source.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The measured formats: a registry of readers, one row each (name, a
 * one-line title, file name extensions).  Index k = 0 .. count - 1;
 * out-of-range indices give NULL.  Formats are detected from the content
 * first (the magic or keywords of each reader, in registry order), then
 * from the extension. */
SB_API size_t sb_measured_format_count(void);
SB_API const char *sb_measured_format_name(size_t k);  /* "merl", "rgl", ... */
SB_API const char *sb_measured_format_title(size_t k); /* "MERL .binary", ... */
SB_API const char *sb_measured_format_exts(size_t k);  /* ".binary", space separated */

typedef enum sb_interp {
    SB_INTERP_DEFAULT = 0, /* MERL: nearest; scattered: the method of lowest
                            * cross-validated error (sb_measured_info_t) */
    SB_INTERP_NEAREST,     /* MERL: the cell containing the pair (as the MERL
                            * reference code); scattered: the nearest sample */
    SB_INTERP_LINEAR,      /* MERL: trilinear in index space between cell
                            * centres, phi_d periodic, missing cells skipped
                            * (weights renormalised); scattered: local linear
                            * least-squares fit of the k nearest */
    SB_INTERP_IDW,         /* scattered: inverse squared distance weights of
                            * the k nearest */
    SB_INTERP_QUADRATIC,   /* scattered: local quadratic least-squares fit of
                            * the k nearest (weights 1/d^2, small ridge),
                            * clamped to the neighbours' range; falls back to
                            * linear, then idw, with too few neighbours */
    SB_INTERP_COUNT_
} sb_interp_t;

/* "default", "nearest", "linear", "idw", "quadratic"; parse returns
 * SB_ERR_UNKNOWN (NULL name included), SB_ERR_ARG for a NULL out. */
SB_API const char *sb_interp_name(sb_interp_t m);
SB_API sb_result_t sb_interp_parse(const char *name, sb_interp_t *out);

/* How spectra are turned into RGB (Cornell .brdf). */
typedef enum sb_white {
    SB_WHITE_E = 0, /* XYZ = sum s(l) cmf(l) / sum ybar(l): a flat spectrum of 1
                     * gives Y = 1 and the equal-energy white E, which in
                     * linear sRGB is (1.2048, 0.9483, 0.9088) (slightly pink) */
    SB_WHITE_D65,   /* as E, then Bradford adaptation from E to D65: a flat
                     * spectrum of 1 gives linear sRGB (1, 1, 1) */
    SB_WHITE_COUNT_
} sb_white_t;

/* What to do with spectral values outside the sRGB gamut (a negative
 * channel after the CIE conversion: saturated colours sRGB cannot show). */
typedef enum sb_gamut {
    SB_GAMUT_KEEP = 0,   /* keep the negative channels (the exact linear map; default) */
    SB_GAMUT_CLIP,       /* set negative channels to 0 */
    SB_GAMUT_DESATURATE, /* keep the luminance Y = 0.2126 R + 0.7152 G + 0.0722 B and
                          * move towards gray (Y, Y, Y) until no channel is negative
                          * (0 when Y <= 0): hue kept, chroma reduced */
    SB_GAMUT_COUNT_
} sb_gamut_t;

/* "keep", "clip", "desaturate"; parse returns SB_ERR_UNKNOWN. */
SB_API const char *sb_gamut_name(sb_gamut_t g);
SB_API sb_result_t sb_gamut_parse(const char *name, sb_gamut_t *out);
/* Map one RGB value by `g`; returns 1 when it was out of gamut (0 for a
 * NULL rgb; a g out of range keeps the value). */
SB_API int sb_gamut_map(sb_gamut_t g, double rgb[3]);

/* Scattered tables: whether values are interpolated relative to a fitted
 * lobe.  A diffuse term plus one Cook-Torrance specular lobe (GGX or
 * exponential D, Smith G, Schlick F; per-channel weights, one width, one
 * F0 or, for a coloured metal, one per channel)
 * is fitted to the samples by least squares in f cos theta_i; the
 * interpolation then works on f / (lobe + floor) and multiplies back, so a
 * highlight held by a few samples keeps its measured shape between them
 * instead of spreading over the neighbours' radius, and a held-out peak
 * sample is predicted by the lobe the others define. */
typedef enum sb_lobe_mode {
    SB_LOBE_AUTO = 0, /* on when it lowers the interpolation's cross-validated error by 10 % */
    SB_LOBE_OFF,      /* the values as measured */
    SB_LOBE_ON,       /* always relative to the lobe */
    SB_LOBE_COUNT_
} sb_lobe_mode_t;

/* "auto", "off", "on"; parse returns SB_ERR_UNKNOWN. */
SB_API const char *sb_lobe_mode_name(sb_lobe_mode_t m);
SB_API sb_result_t sb_lobe_mode_parse(const char *name, sb_lobe_mode_t *out);

/* The lobe fitted to a scattered table (sb_measured_info_t.lobe). */
typedef struct sb_lobe_fit {
    int fitted;           /* 0: not fitted (not a scattered table, or off) */
    int used;             /* the interpolation is relative to it */
    const char *ndf;      /* "ggx", "beckmann", "exp4", "exp8": GGX or exp(-(tan theta_h / alpha)^p)
                           * for p = 2, 4, 8 (static string) */
    double alpha, f0;     /* the D width (GGX alpha, Beckmann m) and Schlick F0 (per channel: f0_rgb) */
    double cos_power;     /* p of the denominator's cosines: 1, 0.5 or 0 */
    int smith_k_remapped; /* Smith-Schlick k = (sqrt(alpha) + 1)^2 / 8; 0: alpha / 2 */
    double kd[3], ks[3];  /* f = kd + ks min(D, d_cap) G F / (4 (cos theta_i cos theta_o)^p)
                           * (kd (1 - (1 - v.h)^5) with diffuse_fresnel) */
    double d_cap;         /* D is at most this, 2x its largest at a sample: the lobe claims
                           * no higher peak between the samples (F, G and the cosines still
                           * grow towards the horizon) */
    double floor[3];      /* added to the lobe before dividing: the median sample value */
    double cv_off, cv_on; /* interpolation CV (the best method) without and with it */
    int f0_per_channel;   /* Schlick's F0 fitted per channel (f0_rgb; f0 their mean), else one for all */
    double f0_rgb[3];     /* each channel's F0 (f0 in each when !f0_per_channel) */
    int diffuse_fresnel;  /* the diffuse term is kd (1 - (1 - v.h)^5) (the light F reflects does
                           * not reach it), else kd */
} sb_lobe_fit_t;

/* Options of sb_measured_open (zero = default everywhere).
 *
 * Scattered tables are interpolated in an embedding of the pair (l, v) in
 * which the symmetries that hold are folded: isotropic tables use
 * (max(theta_i, theta_o), min(theta_i, theta_o), |phi_o - phi_i|) (radians;
 * the sort only when reciprocal), anisotropic ones the polar maps
 * (theta cos phi, theta sin phi) of both directions.  Distances below are
 * Euclidean in that embedding, i.e. roughly angles in radians. */
typedef struct sb_measured_opts {
    const char *format; /* a registry name; NULL or "auto": detect */
    sb_interp_t interp; /* SB_INTERP_DEFAULT: nearest (MERL); scattered: chosen by
                         * cross-validation (see sb_measured_info_t) */
    size_t neighbours;  /* scattered: k nearest samples, 1..64; default 24
                         * (isotropic) or 34 (anisotropic) for the fits,
                         * 4 or 5 for idw */
    double radius;      /* scattered: a pair whose nearest sample is farther
                         * than this is missing (the fit uses samples
                         * within twice this).  0 = auto: 2.5 x the
                         * median distance from a sample to its nearest
                         * other sample.  < 0: no limit */
    sb_white_t white;   /* spectral tables: SB_WHITE_E (default) */
    sb_gamut_t gamut;   /* spectral tables: SB_GAMUT_KEEP (default) */
    /* scattered tables, cross-validation: with cv_folds >= 2, the samples
     * of fold cv_fold (sample i, in the table's order, is in fold
     * sb_measured_fold(i, cv_folds)) are left out of the table; with
     * interp and lobe given too the table is not cross-validated itself
     * (interp_cv NAN, cv_held_out 0: a refit's table uses what the whole
     * table chose) */
    size_t cv_folds, cv_fold;
    sb_lobe_mode_t lobe; /* scattered tables: SB_LOBE_AUTO */
    /* with lobe SB_LOBE_ON, NULL or a lobe whose shape family (ndf, f0,
     * cos_power, smith_k_remapped) is kept: only its width and weights are fitted (the
     * cross-validation's refits keep what the whole table chose) */
    const sb_lobe_fit_t *lobe_shape;
} sb_measured_opts_t;

/* The fold of sample i (the table's order, as sb_source_sample numbers a
 * table's samples: sorted by direction pair and value, whatever the
 * file's row order) among `folds`: a fixed pseudo-random assignment, about
 * equal sizes; 0 for folds < 2. */
SB_API size_t sb_measured_fold(size_t i, size_t folds);

/* What a table held.  Value statistics are over the used samples, of the
 * RGB f_r in 1/sr (MERL: after the channel scales). */
/* One format-specific line of what a table held: `info` prints
 * "key  text", JSON gets the number when there is one, else the text. */
#define SB_MEASURED_FIELDS_MAX 12
typedef struct sb_measured_field {
    char key[24];   /* "description", "layout", "cells", ... */
    char text[232]; /* the value as a person reads it */
    double number;  /* the value when it is a single number; NAN otherwise */
} sb_measured_field_t;

typedef struct sb_measured_info {
    const char *format;              /* registry name of the reader (static string) */
    size_t rows;                     /* data rows read (MERL: cells, 1,458,000) */
    size_t samples;                  /* samples used (MERL: measured cells) */
    size_t missing;                  /* MERL: missing cells (negative or NaN);
                                      * tables: rows skipped (nan_rows + horizon_rows) */
    size_t negative;                 /* values < 0 in the file: MERL missing cells;
                                      * tables: used rows with a negative value (kept:
                                      * measurement noise averages out) */
    size_t out_of_gamut;             /* spectral tables: used rows (RGL: nodes) whose RGB
                                      * had a negative channel (saturated colours outside
                                      * the sRGB gamut), mapped by `gamut` */
    size_t nan_rows;                 /* rows (cells) with a NaN value, skipped */
    size_t horizon_rows;             /* rows with a direction at or below the horizon
                                      * (theta >= pi/2 - 1e-9), skipped */
    size_t channels;                 /* in the file: 1 mono, 3 RGB, n spectral */
    size_t wavelengths;              /* spectral tables: n; otherwise 0 */
    double wl_min, wl_max;           /* nm, spectral tables */
    double theta_i_max, theta_o_max; /* largest elevations used (radians) */
    double value_min[3], value_max[3], value_mean[3];
    unsigned flags;     /* SB_SOURCE_* of the source */
    sb_interp_t interp; /* resolved interpolation */
    size_t neighbours;  /* scattered: k */
    double spacing;     /* scattered: median nearest-other-sample distance */
    double radius;      /* scattered: radius in use (inf when unlimited) */
    size_t dims;        /* scattered: dimension of the embedding (3 or 4) */
    sb_white_t white;
    sb_gamut_t gamut;
    /* Scattered tables: leave-one-position-out cross-validation of each
     * interpolation (index: sb_interp_t; NAN where not computed): held-out
     * samples (at most 2000, evenly spread) predicted from the others and
     * compared with their measured values, relative L2 of f cos cos as the
     * comparable error.  With SB_INTERP_DEFAULT the method of lowest error
     * is used.  cv_missing: held-out samples with no neighbour left within
     * the radius, for the method in use (not in the error). */
    double interp_cv[SB_INTERP_COUNT_];
    size_t cv_held_out, cv_missing;
    sb_lobe_fit_t lobe; /* scattered tables: the fitted lobe */
    size_t nfields;     /* format-specific details, in reading order */
    sb_measured_field_t fields[SB_MEASURED_FIELDS_MAX];
} sb_measured_info_t;

/* A reader of a measured format, as the built-in ones are: sniff() looks
 * at the first bytes of a file (at most 4096) and returns 2 = certainly
 * this format (a magic, a keyword), 1 = plausible (used only when no
 * extension matches), 0 = no; open() reads `path` into a source (e.g.
 * through sb_source_create) with resolved options and an `info` whose
 * `format` is already set (fill what applies: rows, samples, fields via
 * the format's own lines), and reports errors through ctx.  `exts`: file
 * name extensions, space separated (".abc .abd"); title: one line. */
typedef struct sb_measured_reader {
    const char *name, *title, *exts;
    int (*sniff)(const unsigned char *head, size_t n);
    sb_result_t (*open)(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                        sb_measured_info_t *info);
} sb_measured_reader_t;

/* Add a reader to the registry, after the built-in ones (detection tries
 * them first): sb_measured_format_*, `format` of sb_measured_opts_t and
 * sb_source_open on a file then know it.  The descriptor is copied; its
 * strings and functions must outlive every use (static ones do).  Call
 * before opening tables from other threads (not synchronised).
 * SB_ERR_ARG: NULL, or a name, title, exts, sniff or open missing, or the
 * name "auto" or one the registry holds already; SB_ERR_RANGE: the
 * registry is full (16 added readers). */
SB_API sb_result_t sb_measured_register_reader(const sb_measured_reader_t *reader);

/* Open a measured table.  `opts` may be NULL (defaults); `info` may be NULL.
 * The source carries SB_SOURCE_MEASURED, and ISOTROPIC / RECIPROCAL / GRAY
 * where they hold (MERL and Cornell: isotropic and reciprocal; ALTA
 * ISOTROPIC_*: isotropic, reciprocal, gray when mono; CSV: see
 * docs/measured.md).  sb_source_open() calls this with default options for
 * a spec that names a file.
 * Errors (message names the file, and the line for text):
 *   SB_ERR_IO      cannot open or read
 *   SB_ERR_FORMAT  content is not what the format requires: unrecognised,
 *                  wrong size or dims, malformed number, missing columns,
 *                  counts out of range, non-finite angles
 *   SB_ERR_UNSUPPORTED  a recognised but unsupported variant (another ALTA
 *                  parameterisation, a tensor_file version or symmetry
 *                  reduction other than 1.0 and 1, 2, 4)
 *   SB_ERR_ARG / SB_ERR_RANGE  bad options (SB_ERR_UNKNOWN: a format name
 *                  not in the registry)
 *   SB_ERR_NOMEM   the table does not fit in memory or the memory limit
 *                  (opening takes no size option to lower)
 * A file's content never gives SB_ERR_ARG or SB_ERR_RANGE, so a caller
 * can tell bad input from bad options (the CLI: exit 2, not 1). */
SB_API sb_result_t sb_measured_open(sb_context_t *ctx, const char *path, const sb_measured_opts_t *opts,
                                    sb_source_t **out, sb_measured_info_t *info);

/* What the table behind `src` held (a copy kept by sb_measured_open), or
 * NULL for a source not opened by it (analytic models). */
SB_API const sb_measured_info_t *sb_measured_source_info(const sb_source_t *src);

/* ---- errors against the measurements ------------------------------------- */

/* Errors of a reconstruction at the measured samples themselves (every
 * sample of sb_source_sample, no interpolation in between), in the norm of
 * the comparable error: after J' terms
 *   e(J') = sqrt( sum_k sum_c (f~_c - f_c)^2 c_i^2 c_o^2 / sum_k sum_c f_c^2 c_i^2 c_o^2 )
 * with f~ the reconstruction through texture lookups as the GLSL snippet
 * does (sb_factors_eval: form divided back), c_i, c_o the cosines of the
 * sample's directions.  A sample outside the parameterisation's domain
 * counts with f~ = 0 (what a shader returns there). */
#define SB_SAMPLE_ERRORS_MAX 256
typedef struct sb_sample_errors {
    size_t terms;                        /* J' = 1..terms filled (at most 256) */
    size_t samples;                      /* measured samples compared */
    size_t outside;                      /* of them, outside the parameterisation's domain */
    double rel_l2[SB_SAMPLE_ERRORS_MAX]; /* e(J'), index J' - 1 */
    double source_rel_l2;                /* the source itself (its interpolation) at the samples,
                                          * same norm: 0 for a table read exactly
                                          * (RGL: the pole nodes' spread, below 1 %) */
} sb_sample_errors_t;

struct sb_factors;
/* Errors of the first min(J, 256) terms of `f` (parameterisation p, form)
 * at the samples of `src`.  Errors: SB_ERR_ARG (NULL, or a source without
 * samples: analytic models), SB_ERR_NUMERIC (no sample with
 * a non-zero value). */
SB_API sb_result_t sb_measured_sample_errors(sb_context_t *ctx, const sb_source_t *src, const struct sb_factors *f,
                                             const sb_param_t *p, sb_form_t form, sb_sample_errors_t *out);
/* As sb_measured_sample_errors, over the channels of the bit mask
 * `channels` only (1 R, 2 G, 4 B; 0 = all): the others of both the samples
 * and the reconstruction read as 0, as for a fit of those channels
 * (sb_matrix_opts_t.channels).  Same errors. */
SB_API sb_result_t sb_measured_sample_errors_channels(sb_context_t *ctx, const sb_source_t *src,
                                                      const struct sb_factors *f, const sb_param_t *p, sb_form_t form,
                                                      unsigned channels, sb_sample_errors_t *out);

/* Fraction of the cells of `param` for which `src` returns a value (1 for
 * analytic sources): *known of *cells cells with both directions above the
 * horizon.  Evaluates every cell once (in parallel).  Either output may be
 * NULL. */
SB_API sb_result_t sb_measured_coverage(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                        size_t *known, size_t *cells);

/* The coverage per pair of elevation bands: known[a * bands + b] of
 * cells[a * bands + b] cells of `param` with theta_i in band a and theta_o
 * in band b (bands of 90/bands degrees), so that users see which regions
 * hold data.  bands 1..90; both arrays hold bands^2 counts.  Errors:
 * SB_ERR_ARG, SB_ERR_NOMEM, SB_ERR_OVERFLOW. */
SB_API sb_result_t sb_measured_coverage_map(sb_context_t *ctx, const sb_source_t *src, const sb_param_t *param,
                                            size_t bands, size_t *known, size_t *cells);

/* ---- MERL ------------------------------------------------------------- */

#define SB_MERL_TH 90
#define SB_MERL_TD 90
#define SB_MERL_PD 180
#define SB_MERL_CELLS ((size_t)SB_MERL_TH * SB_MERL_TD * SB_MERL_PD)
#define SB_MERL_FILE_SIZE ((size_t)12 + 3 * 8 * SB_MERL_CELLS) /* 34,992,012 bytes */

/* Channel scales: f_r,c = stored value x scale[c]. */
extern const double sb_merl_scale[3];

/* Rusinkiewicz half/difference angles of a pair: h = normalize(wi + wo),
 * theta_h, phi_h its angles; d = wi rotated by -phi_h about z, then by
 * -theta_h about y; theta_d, phi_d its angles, phi_d in [0, 2 pi).
 * Conventions for the degenerate cases: phi_h = 0 when sin theta_h <= 1e-12
 * (h along the normal), phi_d = 0 when sin theta_d <= 1e-12 (wi = wo).
 * Returns 0 when h is undefined (wi = -wo, |wi + wo| <= 1e-12) or an
 * argument is NULL. */
SB_API int sb_half_diff_angles(const double wi[3], const double wo[3], double *theta_h, double *theta_d, double *phi_d);
/* The inverse with phi_h = 0; returns 1 when both directions are strictly
 * above the horizon. */
SB_API int sb_half_diff_dirs(double theta_h, double theta_d, double phi_d, double wi[3], double wo[3]);

/* MERL cell of a pair (the reference code's nearest cell); returns 0 when
 * the pair has a direction at or below the horizon, or wi = -wo. */
SB_API int sb_merl_index(const double wi[3], const double wo[3], size_t *index);
/* Directions at the centre of a cell (index space + 1/2 on each axis, phi_h
 * = 0); returns 1 when both are above the horizon, 0 for an index >=
 * SB_MERL_CELLS or a NULL output. */
SB_API int sb_merl_cell_dirs(size_t index, double wi[3], double wo[3]);

/* What a converted file leaves out (sb_merl_write_stats,
 * sb_measured_write_csv_stats); NULL or zero = the defaults, which write
 * only what the target format holds faithfully. */
typedef struct sb_write_opts {
    /* MERL: cells whose value lies above the largest the source measured
     * (value_measured below: extrapolated, not measured) are written as
     * missing (-1) unless this is non-zero */
    int keep_extrapolated;
    /* a source that stores f cos theta_i (SB_SOURCE_STORES_COS: an RGL
     * file): CSV samples and MERL cells whose light lies within this angle
     * of the horizon (theta_i >= 90 deg - horizon_deg) are left out
     * (missing, -1, in MERL), as f there is the stored value over a cosine
     * near 0 (up to 1e9 1/sr); 0 = 1 deg, negative = keep them */
    double horizon_deg;
} sb_write_opts_t;

/* Write `src` as a MERL file: each cell holds f_r at the cell's centre
 * divided by the channel scale, or -1 (missing) where the centre pair is
 * not above the horizon, the source is missing or not finite there, or
 * (sb_write_opts_t, defaults) the value lies above the largest the source
 * measured or the source stores f cos theta_i and the light lies within
 * 1 deg of the horizon.  Evaluated in parallel; written to a
 * temporary name, then renamed.  Errors: SB_ERR_ARG, SB_ERR_NOMEM,
 * SB_ERR_IO. */
SB_API sb_result_t sb_merl_write(sb_context_t *ctx, const char *path, const sb_source_t *src);
/* What sb_merl_write_stats wrote: cells with a value (the others -1),
 * the largest f_r written, and, for a measured source, the cells above
 * the largest value it measured (value_measured: a table's own range;
 * interpolation between samples stays inside it, so these are
 * extrapolated, e.g. an RGL table's f cos theta_o divided by a grazing
 * cos theta_o; written as missing unless kept), the largest of them
 * (above_max, 0 when none) and the smallest theta_d index among them. */
typedef struct sb_merl_write_stats {
    size_t cells, written, above;
    double value_max, value_measured; /* f_r, 1/sr; value_measured NaN for a model */
    size_t above_td_min;              /* SB_MERL_TD when none */
    double above_max;                 /* f_r, 1/sr */
    size_t grazing;                   /* cells left missing for their light's horizon (horizon_deg) */
    double horizon_deg;               /* the bound applied, 0 when none */
} sb_merl_write_stats_t;
/* sb_merl_write with options (may be NULL), and what it wrote into *stats
 * (may be NULL). */
SB_API sb_result_t sb_merl_write_stats(sb_context_t *ctx, const char *path, const sb_source_t *src,
                                       const sb_write_opts_t *opts, sb_merl_write_stats_t *stats);

/* ---- conversion ----------------------------------------------------------- */

/* Write the measured samples of `src` (sb_source_sample: as read, no
 * interpolation) as a sepbrdf CSV table to fp: degrees, the source's
 * symmetry and reciprocity as metadata, RGB f_r with 17 digits, so that
 * reading it back gives the same samples; a source that stores f cos
 * theta_i leaves out the samples with its light within 1 deg of the
 * horizon (sb_write_opts_t.horizon_deg).  *rows (may be NULL) receives
 * the number written.  Errors: SB_ERR_ARG (no samples: a model; measure
 * those with sb_gonio_write_csv), SB_ERR_IO. */
SB_API sb_result_t sb_measured_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, size_t *rows);
/* What sb_measured_write_csv_stats wrote: rows, the samples left out for
 * their light's nearness to the horizon, the largest value among those
 * (max over channels, 1/sr; 0 when none) and the bound applied (degrees
 * from the horizon; 0 when none: the source does not store f cos). */
typedef struct sb_csv_write_stats {
    size_t rows, left_out;
    double left_out_max, horizon_deg;
} sb_csv_write_stats_t;
/* sb_measured_write_csv with options (may be NULL), and what it wrote into
 * *stats (may be NULL). */
SB_API sb_result_t sb_measured_write_csv_stats(sb_context_t *ctx, FILE *fp, const sb_source_t *src,
                                               const sb_write_opts_t *opts, sb_csv_write_stats_t *stats);

/* ---- simulated gonioreflectometer ------------------------------------- */

/* Detector grid: theta_k = (k + 1/2) 90 deg / N_theta (cell centres of
 * [0, 90] deg, so the horizon is never measured) and phi_k = k 360 deg /
 * N_phi (the plane of incidence is included), for the light (i) and the
 * detector (o).  The "spacing" is 90/N_theta and 360/N_phi degrees. */
typedef struct sb_gonio_opts {
    size_t n_theta_i, n_phi_i, n_theta_o, n_phi_o; /* 0 = 18, 1, 18, 72 (5 deg) */
    double noise;                                  /* sigma of multiplicative Gaussian noise: v (1 + sigma z),
                                                    * z ~ N(0, 1) per value; 0 = none (may give v < 0) */
    uint64_t seed;                                 /* of the noise; 0 = 1 */
} sb_gonio_opts_t;

/* Measure `src` on the detector grid and write a sepbrdf CSV table to fp
 * (rows where the source is missing are left out; *rows, if not NULL,
 * receives the number written).  Errors: SB_ERR_ARG, SB_ERR_RANGE (grid
 * sizes 1..4096, noise 0..10), SB_ERR_OVERFLOW (more than 2^31 rows),
 * SB_ERR_IO. */
SB_API sb_result_t sb_gonio_write_csv(sb_context_t *ctx, FILE *fp, const sb_source_t *src, const sb_gonio_opts_t *opts,
                                      size_t *rows);

/* ---- spectra ------------------------------------------------------------ */

/* CIE 1931 2 deg colour matching functions (x, y, z bar) at `nm`, linear
 * between the embedded 1 nm table (380..780 nm), 0 outside. */
SB_API void sb_cie_cmf(double nm, double xyz[3]);

/* Linear weights w[c * n + k] such that linear sRGB_c = sum_k w[c n + k]
 * s_k for a spectrum sampled at n increasing wavelengths (nm): s is taken
 * piecewise linear between the samples and constant beyond the ends,
 * integrated against the CMFs at 1 nm, normalised by sum ybar (white E),
 * optionally adapted to D65, and mapped by the IEC 61966-2-1 XYZ -> linear
 * sRGB matrix.  Errors: SB_ERR_ARG (NULL nm or w, unknown white),
 * SB_ERR_RANGE (n == 0, wavelengths not finite or not increasing),
 * SB_ERR_OVERFLOW (3 n doubles overflow: n cannot be an array's length). */
SB_API sb_result_t sb_spectral_weights(sb_context_t *ctx, const double *nm, size_t n, sb_white_t white, double *w);

#ifdef __cplusplus
}
#endif
#endif
