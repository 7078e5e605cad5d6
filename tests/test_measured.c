/* Measured tables: MERL reader/writer and index mapping, scattered tables
 * (Cornell, ALTA, CSV), interpolation, coverage, spectra, hostile files. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fixtures.h"
#include "harness.h"
#include "measured_util.h"
#include "sepbrdf/sepbrdf.h"

#define NCELLS (90 * 90 * 180)
static const double scale[3] = {1.0 / 1500, 1.15 / 1500, 1.66 / 1500};

static char path_buf[4][4096];

/* A path in a fresh temporary directory (4 rotating buffers). */
static const char *tmp_path(const char *tag, const char *name) {
    static int k;
    char *b = path_buf[k++ % 4];
    int n = snprintf(b, 4096, "%s/%s", sb_tmpdir(tag), name);
    CHECK(n > 0 && n < 4096);
    return b;
}

static int has_measured_dir(void) {
    struct stat st;
    return stat(SB_MEASURED_DIR, &st) == 0 && S_ISDIR(st.st_mode);
}

/* Open a table; on failure report the message. */
static sb_source_t *open_table(const char *path, const sb_measured_opts_t *o, sb_measured_info_t *info) {
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *s = NULL;
    sb_result_t r = sb_measured_open(ctx, path, o, &s, info);
    CHECKF(r == SB_OK, "open %s: %s", path, sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    return s;
}

/* ---- an independent MERL index ------------------------------------------- */

static void mat_vec(const double m[3][3], const double v[3], double out[3]) {
    for (int i = 0; i < 3; i++)
        out[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
}

/* Rusinkiewicz angles of (l, v) by explicit rotation matrices (a[0..3] =
 * theta_h, phi_h, theta_d, phi_d; phi_d in (-pi, pi]). */
static void ref_halfdiff(const double l[3], const double v[3], double a[4]) {
    double h[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    double n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    for (int k = 0; k < 3; k++)
        h[k] /= n;
    double th = acos(h[2]), ph = atan2(h[1], h[0]);
    const double rz[3][3] = {{cos(ph), sin(ph), 0}, {-sin(ph), cos(ph), 0}, {0, 0, 1}};
    const double ry[3][3] = {{cos(th), 0, -sin(th)}, {0, 1, 0}, {sin(th), 0, cos(th)}};
    double t[3], d[3];
    mat_vec(rz, l, t);
    mat_vec(ry, t, d);
    a[0] = th, a[1] = ph, a[2] = acos(d[2] > 1 ? 1 : d[2]), a[3] = atan2(d[1], d[0]);
}

/* The MERL bins of the reference code (BRDFRead.cpp). */
static size_t ref_index(const double l[3], const double v[3]) {
    double a[4];
    ref_halfdiff(l, v, a);
    double th = a[0], td = a[2], pd = a[3];
    if (pd < 0) pd += SB_PI; /* the reference folds (-pi, 0) onto (0, pi) */
    if (pd >= SB_PI) pd -= SB_PI;
    int ih = th <= 0 ? 0 : (int)(sqrt(th / (SB_PI / 2)) * 90);
    int id = (int)(td / (SB_PI / 2) * 90), ip = (int)(pd / SB_PI * 180);
    ih = ih < 0 ? 0 : ih > 89 ? 89 : ih;
    id = id < 0 ? 0 : id > 89 ? 89 : id;
    ip = ip < 0 ? 0 : ip > 179 ? 179 : ip;
    return (size_t)ip + 180 * ((size_t)id + 90 * (size_t)ih);
}

static void put_le32(unsigned char *b, uint32_t u) {
    for (int k = 0; k < 4; k++)
        b[k] = (unsigned char)(u >> (8 * k));
}
static void put_le64(unsigned char *b, double d) {
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    for (int k = 0; k < 8; k++)
        b[k] = (unsigned char)(u >> (8 * k));
}
static double get_le64(const unsigned char *b) {
    uint64_t u = 0;
    for (int k = 7; k >= 0; k--)
        u = u << 8 | b[k];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* A MERL file written here, byte by byte: dims, then `values` doubles of
 * value(i) (i over the 3 planes), then `extra` zero bytes. */
static void write_merl_raw(const char *path, const int32_t dims[3], size_t values, double (*value)(size_t),
                           size_t extra) {
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (!fp) return;
    unsigned char b[12];
    for (int k = 0; k < 3; k++)
        put_le32(b + 4 * k, (uint32_t)dims[k]);
    fwrite(b, 1, 12, fp);
    for (size_t i = 0; i < values; i++) {
        put_le64(b, value(i));
        fwrite(b, 1, 8, fp);
    }
    for (size_t i = 0; i < extra; i++)
        fputc(0, fp);
    fclose(fp);
}

/* Cell k holds k + 1 in every plane; cells 7 and 1000 (mod NCELLS) are missing. */
static double index_value(size_t i) {
    size_t k = i % NCELLS;
    return (k == 7 || k == 1000) ? -1.0 : (double)(k + 1);
}

static const int32_t merl_dims[3] = {90, 90, 180};

static void random_dir(unsigned long long *s, double w[3]) {
    double ct = sb_rand01(s) * 0.999 + 0.0005, ph = 2 * SB_PI * sb_rand01(s), st = sqrt(1 - ct * ct);
    w[0] = st * cos(ph);
    w[1] = st * sin(ph);
    w[2] = ct;
}

/* The reader maps pairs to cells as the reference code does: an encoded
 * file returns k + 1 at cell k, times the channel scales. */
SB_TEST(merl_index_mapping) {
    const char *path = tmp_path("merl", "index.binary");
    write_merl_raw(path, merl_dims, 3 * (size_t)NCELLS, index_value, 0);
    sb_measured_info_t info;
    sb_source_t *s = open_table(path, NULL, &info);
    if (!s) return;
    CHECK(strcmp(info.format, "merl") == 0 && info.rows == NCELLS);
    CHECK(info.missing == 2 && info.negative == 2 && info.samples == NCELLS - 2);
    CHECK(sb_source_flags(s) == (SB_SOURCE_MEASURED | SB_SOURCE_ISOTROPIC | SB_SOURCE_RECIPROCAL));
    unsigned long long seed = 12345;
    int bad = 0;
    for (int n = 0; n < 20000; n++) {
        double l[3], v[3], rgb[3];
        random_dir(&seed, l);
        random_dir(&seed, v);
        size_t want = ref_index(l, v), got = 0;
        CHECK(sb_merl_index(l, v, &got) == 1);
        int known = sb_source_eval(s, l, v, rgb);
        if (want == 7 || want == 1000) {
            CHECK(known == 0 && rgb[0] == 0);
            continue;
        }
        CHECK(known == 1);
        double k = rgb[0] / scale[0] - 1;
        if (got != want || fabs(k - (double)want) > 1e-6) bad++;
        for (int c = 0; c < 3; c++)
            CHECK_REL(rgb[c], (double)(want + 1) * scale[c], 1e-12);
    }
    CHECKF(bad == 0, "%d of 20000 random pairs mapped to another cell", bad);
    sb_source_destroy(s);
}

/* A file written from an analytic model reads back the model at the cell
 * centres (as stored: value / scale, little-endian, channel-planar). */
SB_TEST(merl_write_read_model) {
    const char *path = tmp_path("merl", "gold.binary");
    sb_source_t *m = fx_model("microfacet:base=gold,roughness=0.5");
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_result_t r = sb_merl_write(ctx, path, m);
    CHECKF(r == SB_OK, "%s", sb_context_last_error(ctx));
    sb_context_destroy(ctx);
    struct stat st;
    CHECK(stat(path, &st) == 0 && (size_t)st.st_size == SB_MERL_FILE_SIZE);
    /* the bytes, read here */
    FILE *fp = fopen(path, "rb");
    unsigned char *raw = malloc(SB_MERL_FILE_SIZE);
    CHECK(fp && raw && fread(raw, 1, SB_MERL_FILE_SIZE, fp) == SB_MERL_FILE_SIZE);
    if (fp) fclose(fp);
    sb_source_t *s = NULL;
    sb_context_create(&ctx);
    CHECK(sb_source_open(ctx, path, &s) == SB_OK); /* through the hook */
    sb_context_destroy(ctx);
    if (!s || !raw) {
        free(raw);
        sb_source_destroy(m);
        sb_source_destroy(s);
        return;
    }
    CHECK(raw[0] == 90 && raw[4] == 90 && raw[8] == 180 && raw[9] == 0);
    size_t checked = 0, missing = 0;
    for (size_t k = 0; k < NCELLS; k += 97) {
        size_t ip = k % 180, id = k / 180 % 90, ih = k / 180 / 90;
        /* the centre, computed here: theta_h on the square-root scale */
        double uh = (ih + 0.5) / 90, th = uh * uh * SB_PI / 2, td = (id + 0.5) / 90 * SB_PI / 2,
               pd = (ip + 0.5) / 180 * SB_PI;
        double d[3] = {sin(td) * cos(pd), sin(td) * sin(pd), cos(td)};
        double l[3] = {d[0] * cos(th) + d[2] * sin(th), d[1], -d[0] * sin(th) + d[2] * cos(th)};
        double h[3] = {sin(th), 0, cos(th)}, lh = l[0] * h[0] + l[2] * h[2];
        double v[3] = {2 * lh * h[0] - l[0], 2 * lh * h[1] - l[1], 2 * lh * h[2] - l[2]};
        double want[3], got[3];
        if (l[2] <= 0 || v[2] <= 0) {
            for (int c = 0; c < 3; c++)
                CHECK(get_le64(raw + 12 + 8 * ((size_t)c * NCELLS + k)) == -1.0);
            missing++;
            continue;
        }
        CHECK(ref_index(l, v) == k);
        sb_source_eval(m, l, v, want);
        CHECK(sb_source_eval(s, l, v, got) == 1);
        for (int c = 0; c < 3; c++) {
            CHECK_REL(got[c], want[c], 1e-12);
            CHECK_REL(get_le64(raw + 12 + 8 * ((size_t)c * NCELLS + k)) * scale[c], want[c], 1e-12);
        }
        checked++;
    }
    CHECK(checked > 5000 && missing > 1000);
    free(raw);
    sb_source_destroy(s);
    sb_source_destroy(m);
}

/* Conventions at the degenerate configurations. */
SB_TEST(merl_degenerate) {
    const char *path = tmp_path("merl", "deg.binary");
    write_merl_raw(path, merl_dims, 3 * (size_t)NCELLS, index_value, 0);
    sb_source_t *s = open_table(path, NULL, NULL);
    if (!s) return;
    double rgb[3];
    /* theta_h = 0 (v the mirror of l): phi_h = 0, so phi_d = phi_l, folded */
    for (double phi = 0.1; phi < 2 * SB_PI; phi += 0.7) {
        double th = 0.6, l[3], v[3];
        sb_dir_from_angles(th, phi, l);
        v[0] = -l[0];
        v[1] = -l[1];
        v[2] = l[2];
        double a, b, c;
        CHECK(sb_half_diff_angles(l, v, &a, &b, &c) == 1);
        CHECK_ABS(a, 0, 1e-12);
        CHECK_REL(b, th, 1e-12);
        CHECK_ABS(c, phi, 1e-9);
        double pf = phi >= SB_PI ? phi - SB_PI : phi;
        size_t want = (size_t)(pf / SB_PI * 180) + 180 * (size_t)(th / (SB_PI / 2) * 90);
        CHECK(sb_source_eval(s, l, v, rgb) == 1);
        CHECK_REL(rgb[0] / scale[0] - 1, (double)want, 1e-9);
    }
    /* theta_d = 0 (l = v): phi_d = 0 */
    for (double th = 0.05; th < 1.5; th += 0.3) {
        double l[3], a, b, c;
        sb_dir_from_angles(th, 2.0, l);
        CHECK(sb_half_diff_angles(l, l, &a, &b, &c) == 1);
        CHECK(c == 0);
        CHECK_ABS(b, 0, 1e-7);
        size_t want = 180 * 90 * (size_t)(sqrt(th / (SB_PI / 2)) * 90);
        CHECK(sb_source_eval(s, l, l, rgb) == 1);
        CHECK_REL(rgb[0] / scale[0] - 1, (double)want, 1e-9);
    }
    /* l = -v: no half vector; any pair below the horizon is missing */
    double l[3] = {0.3, 0.4, sqrt(0.75)}, v[3] = {-0.3, -0.4, -sqrt(0.75)}, a, b, c;
    CHECK(sb_half_diff_angles(l, v, &a, &b, &c) == 0);
    CHECK(sb_source_eval(s, l, v, rgb) == 0 && rgb[0] == 0 && rgb[1] == 0 && rgb[2] == 0);
    double g1[3] = {1, 0, 0}, g2[3] = {-1, 0, 0};
    CHECK(sb_source_eval(s, g1, g2, rgb) == 0);
    size_t k;
    CHECK(sb_merl_index(l, v, &k) == 0);
    sb_source_destroy(s);
}

static double smooth_value(size_t i) {
    size_t k = i % NCELLS, id = k / 180 % 90, ih = k / 180 / 90;
    if (k == 180 * (40 + 90 * 40) + 20) return -1; /* one missing cell */
    return 1 + (double)ih + 2 * (double)id;
}

/* Trilinear mode: exact on a field linear in the index coordinates, equal
 * to the cell at its centre, missing at the centre of a missing cell. */
SB_TEST(merl_linear) {
    const char *path = tmp_path("merl", "lin.binary");
    write_merl_raw(path, merl_dims, 3 * (size_t)NCELLS, smooth_value, 0);
    sb_measured_opts_t o = {0};
    o.interp = SB_INTERP_LINEAR;
    sb_measured_info_t info;
    sb_source_t *s = open_table(path, &o, &info);
    if (!s) return;
    CHECK(info.interp == SB_INTERP_LINEAR);
    unsigned long long seed = 99;
    int n = 0;
    for (int it = 0; it < 5000; it++) {
        double l[3], v[3], rgb[3], th, td, pd;
        random_dir(&seed, l);
        random_dir(&seed, v);
        sb_half_diff_angles(l, v, &th, &td, &pd);
        double uh = 90 * sqrt(th / (SB_PI / 2)) - 0.5, ud = 90 * td / (SB_PI / 2) - 0.5;
        if (uh < 0 || uh > 89 || ud < 0 || ud > 89) continue;
        if (fabs(uh - 40) < 1.5 && fabs(ud - 40) < 1.5) continue; /* near the missing cell */
        CHECK(sb_source_eval(s, l, v, rgb) == 1);
        CHECK_REL(rgb[0] / scale[0], 1 + uh + 2 * ud, 1e-9);
        n++;
    }
    CHECK(n > 1000);
    double l[3], v[3], rgb[3];
    CHECK(sb_merl_cell_dirs(180 * (41 + 90 * 40) + 20, l, v) == 1);
    CHECK(sb_source_eval(s, l, v, rgb) == 1);
    CHECK_REL(rgb[2] / scale[2], 1 + 40 + 2 * 41, 1e-9);
    /* at the missing cell: the neighbours' values (renormalised) or missing;
     * nearest mode: missing */
    CHECK(sb_merl_cell_dirs(180 * (40 + 90 * 40) + 20, l, v) == 1);
    if (sb_source_eval(s, l, v, rgb)) CHECK(rgb[0] / scale[0] >= 1 + 39 + 78 && rgb[0] / scale[0] <= 1 + 41 + 82);
    sb_source_destroy(s);
    s = open_table(path, NULL, NULL);
    if (!s) return;
    CHECK(sb_source_eval(s, l, v, rgb) == 0 && rgb[0] == 0);
    sb_source_destroy(s);
}

static double zero_value(size_t i) {
    (void)i;
    return 0.5;
}

SB_TEST(merl_hostile) {
    const char *dir = sb_tmpdir("merl");
    char p[4200];
    /* truncated: header right, body short */
    snprintf(p, sizeof p, "%s/trunc.binary", dir);
    write_merl_raw(p, merl_dims, 1000, zero_value, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "expected 34992012");
    /* oversized */
    snprintf(p, sizeof p, "%s/over.binary", dir);
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, zero_value, 5);
    expect_fail(p, NULL, SB_ERR_FORMAT, "file size 34992017 bytes");
    /* wrong dims, 2^31 - 1 dims, negative dims: the header is checked first */
    const int32_t wrong[3] = {90, 90, 90}, huge[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, neg[3] = {-90, 90, 180};
    snprintf(p, sizeof p, "%s/dims.binary", dir);
    write_merl_raw(p, wrong, 3 * 90 * 90 * 90, zero_value, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "dims 90 x 90 x 90, expected 90 x 90 x 180");
    snprintf(p, sizeof p, "%s/huge.binary", dir);
    write_merl_raw(p, huge, 10, zero_value, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "dims 2147483647 x 2147483647 x 2147483647");
    snprintf(p, sizeof p, "%s/neg.binary", dir);
    write_merl_raw(p, neg, 10, zero_value, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "dims -90 x 90 x 180");
    /* short header, empty */
    snprintf(p, sizeof p, "%s/short.binary", dir);
    write_text(p, "\x5a\x00");
    expect_fail(p, NULL, SB_ERR_FORMAT, "truncated header");
    snprintf(p, sizeof p, "%s/empty.binary", dir);
    write_text(p, "");
    expect_fail(p, NULL, SB_ERR_FORMAT, "truncated header");
    /* MERL takes nearest or linear only */
    snprintf(p, sizeof p, "%s/ok.binary", dir);
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, zero_value, 0);
    sb_measured_opts_t o = {0};
    o.interp = SB_INTERP_IDW;
    expect_fail(p, &o, SB_ERR_ARG, "nearest");
    /* the writer: unwritable folder, nothing left behind */
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_source_t *m = fx_model("lambert:albedo=0.5");
    snprintf(p, sizeof p, "%s/no/such/dir/x.binary", dir);
    CHECK(sb_merl_write(ctx, p, m) == SB_ERR_IO);
    CHECK(strstr(sb_context_last_error(ctx), p) != NULL);
    sb_source_destroy(m);
    sb_context_destroy(ctx);
}

/* A MERL file with every cell missing is an error, not a perfect fit; a
 * cell beyond float storage is found when the file is read. */
static double all_missing(size_t i) {
    (void)i;
    return -1;
}
static double one_huge(size_t i) { return i == 5 ? 1e300 : 1; }
static double all_infinite(size_t i) {
    (void)i;
    return INFINITY;
}

SB_TEST(merl_no_sample_overflow) {
    const char *dir = sb_tmpdir("merl");
    char p[4200];
    snprintf(p, sizeof p, "%s/missing.binary", dir);
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, all_missing, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "no measured cell (all 1458000 missing: 1458000 negative");
    /* an infinite cell is counted as what it is (hsw3: it read "NaN") */
    snprintf(p, sizeof p, "%s/infinite.binary", dir);
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, all_infinite, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "0 negative, 1458000 NaN or infinite)");
    snprintf(p, sizeof p, "%s/huge.binary", dir);
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, one_huge, 0);
    expect_fail(p, NULL, SB_ERR_FORMAT, "cell 5 (theta_h 0, theta_d 0, phi_d 5) channel 0");
}

/* Angles in the domain but below the horizon (90..180 deg) are skipped
 * and counted, not refused. */
SB_TEST(angles_below_horizon_counted) {
    const char *p = tmp_path("dom", "below.csv");
    write_text(p, "# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1\n"
                  "120,0,10,180,1\n10,-300,20,350,1\n");
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    if (!s) return;
    CHECK(info.rows == 3 && info.samples == 2 && info.horizon_rows == 1);
    sb_source_destroy(s);
}

/* Line endings CR LF and CR alone, and a UTF-8 byte order mark, read as
 * the plain file does (same samples, same values). */
SB_TEST(csv_cr_bom) {
    static const char *const rows[] = {"# units: degrees", "theta_i,phi_i,theta_o,phi_o,r,g,b", "10,0,10,180,1,2,3",
                                       "30,0,20,90,4,5,6", "50,0,40,0,7,8,9"};
    static const char *const ends[] = {"\n", "\r\n", "\r", "\n"};
    double ref[3] = {0, 0, 0};
    for (int v = 0; v < 4; v++) {
        char text[512] = "", name[32];
        if (v == 3) strcat(text, "\xef\xbb\xbf");
        for (int k = 0; k < 5; k++) {
            strcat(text, rows[k]);
            strcat(text, ends[v]);
        }
        snprintf(name, sizeof name, "t%d.csv", v);
        const char *p = tmp_path("crbom", name);
        write_text(p, text);
        sb_measured_info_t info;
        sb_source_t *s = open_table(p, NULL, &info);
        CHECKF(s != NULL, "variant %d", v);
        if (!s) continue;
        CHECKF(info.rows == 3 && info.samples == 3 && info.channels == 3, "variant %d: %zu rows", v, info.rows);
        double wi[3] = {sin(30 * SB_PI / 180), 0, cos(30 * SB_PI / 180)},
               wo[3] = {0, sin(20 * SB_PI / 180), cos(20 * SB_PI / 180)}, rgb[3];
        CHECK(sb_source_eval(s, wi, wo, rgb) == 1);
        if (v == 0) memcpy(ref, rgb, sizeof ref);
        for (int c = 0; c < 3; c++)
            CHECK(rgb[c] == ref[c]);
        sb_source_destroy(s);
    }
}

/* ---- spectra ------------------------------------------------------------ */

SB_TEST(spectral_white) {
    /* the CMF table, read here from the project's copy */
    FILE *fp = fopen(SB_SOURCE_DIR "/data/cie1931_2deg_1nm.csv", "r");
    CHECK(fp != NULL);
    if (!fp) return;
    char line[256];
    double sum[3] = {0, 0, 0}, at550[3] = {0, 0, 0};
    int rows = 0;
    while (fgets(line, sizeof line, fp)) {
        double nm, x, y, z;
        if (sscanf(line, "%lf,%lf,%lf,%lf", &nm, &x, &y, &z) != 4) continue;
        sum[0] += x;
        sum[1] += y;
        sum[2] += z;
        if (nm == 550) {
            at550[0] = x;
            at550[1] = y;
            at550[2] = z;
        }
        rows++;
    }
    fclose(fp);
    CHECK(rows == 401);
    for (int c = 0; c < 3; c++)
        CHECK_REL(sum[c], 106.86, 2e-3); /* the README's check */
    double cmf[3];
    sb_cie_cmf(550, cmf);
    for (int c = 0; c < 3; c++)
        CHECK_REL(cmf[c], at550[c], 1e-15);
    sb_cie_cmf(379, cmf);
    CHECK(cmf[0] == 0 && cmf[1] == 0);

    /* a flat spectrum of 1: E white, Y = 1 */
    static const double m[3][3] = {
        {3.2404542, -1.5371385, -0.4985314}, {-0.9692660, 1.8760108, 0.0415560}, {0.0556434, -0.2040259, 1.0572252}};
    double xyz[3] = {sum[0] / sum[1], 1, sum[2] / sum[1]}, e[3];
    for (int c = 0; c < 3; c++)
        e[c] = m[c][0] * xyz[0] + m[c][1] * xyz[1] + m[c][2] * xyz[2];
    double nm[31], w[93];
    for (int k = 0; k < 31; k++)
        nm[k] = 400 + 10 * k;
    CHECK(sb_spectral_weights(NULL, nm, 31, SB_WHITE_E, w) == SB_OK);
    for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int k = 0; k < 31; k++)
            s += w[c * 31 + k];
        CHECK_REL(s, e[c], 1e-12);
    }
    CHECK_REL(e[0], 1.2048, 1e-3);
    CHECK_REL(e[1], 0.9483, 1e-3);
    CHECK_REL(e[2], 0.9088, 1e-3);
    /* D65: a flat spectrum is RGB (1, 1, 1) */
    CHECK(sb_spectral_weights(NULL, nm, 31, SB_WHITE_D65, w) == SB_OK);
    for (int c = 0; c < 3; c++) {
        double s = 0;
        for (int k = 0; k < 31; k++)
            s += w[c * 31 + k];
        CHECK_ABS(s, 1, 1e-3);
    }
    /* a 1 nm spike at 550 nm gives the CMF there over sum(ybar) */
    double spike_nm[3] = {549, 550, 551}, ws[9];
    CHECK(sb_spectral_weights(NULL, spike_nm, 3, SB_WHITE_E, ws) == SB_OK);
    double srgb_y = 0;
    for (int c = 0; c < 3; c++)
        srgb_y += (c == 0 ? 0.2126729 : c == 1 ? 0.7151522 : 0.0721750) * ws[c * 3 + 1];
    CHECK_REL(srgb_y, at550[1] / sum[1], 2e-4); /* Y of linear sRGB recovers Y */
    /* bad wavelengths */
    double bad[2] = {500, 500};
    CHECK(sb_spectral_weights(NULL, bad, 2, SB_WHITE_E, ws) == SB_ERR_RANGE);
    CHECK(sb_spectral_weights(NULL, bad, 0, SB_WHITE_E, ws) == SB_ERR_RANGE);
}

/* ---- shared real data ---------------------------------------------------- */

SB_TEST(cornell_shared) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    if (sb_test_failed_now()) return;
    const char *path = SB_MEASURED_DIR "/cornell_acryl_blue.brdf";
    sb_measured_info_t info;
    sb_source_t *s = open_table(path, NULL, &info);
    if (!s) return;
    CHECK(strcmp(info.format, "cornell") == 0);
    CHECK(info.rows == 1439 && info.samples == 1439 && info.missing == 0);
    CHECK(info.wavelengths == 31 && info.channels == 31);
    CHECK(info.wl_min == 400 && info.wl_max == 700);
    CHECK(info.negative == 0);
    CHECKF(info.value_mean[2] > info.value_mean[0] && info.value_mean[2] > info.value_mean[1],
           "not blue: mean RGB %g %g %g", info.value_mean[0], info.value_mean[1], info.value_mean[2]);
    CHECK(sb_source_flags(s) & SB_SOURCE_ISOTROPIC);
    /* at a measured position the table returns the sample's RGB: reciprocal too */
    double l[3], v[3], a[3], b[3];
    sb_dir_from_angles(0.872665, 0, l);
    sb_dir_from_angles(0.573513, 0, v);
    CHECK(sb_source_eval(s, l, v, a) == 1 && sb_source_eval(s, v, l, b) == 1);
    for (int c = 0; c < 3; c++)
        CHECK_REL(a[c], b[c], 1e-12);
    CHECK(a[2] > a[0]);
    /* coverage on io R = 16 */
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    po.res = 16;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK);
    size_t known = 0, cells = 0;
    CHECK(sb_measured_coverage(NULL, s, p, &known, &cells) == SB_OK);
    CHECK(cells == 65536 && known > cells / 2 && known < cells);
    /* the matrix masks exactly the missing cells */
    sb_matrix_t m;
    CHECK(sb_matrix_build(NULL, s, p, NULL, &m) == SB_OK);
    CHECK(m.valid_count == known && m.mask != NULL);
    sb_matrix_free(&m);
    sb_param_destroy(p);
    sb_source_destroy(s);
}

/* The count of numbers on a line. */
static int line_numbers(const char *line) {
    int n = 0;
    char *e;
    for (const char *p = line;; p = e, n++) {
        strtod(p, &e);
        if (e == p) return n;
    }
}

/* The acrylic without sample `drop` (reading order: the data rows are the
 * lines of the most numbers, a wavelength line has fewer) as a temporary
 * Cornell file, the other lines copied as they are. */
static const char *cornell_without(size_t drop, const char *name) {
    FILE *in = fopen(SB_MEASURED_DIR "/cornell_acryl_blue.brdf", "r");
    const char *out = tmp_path("heldout", name);
    FILE *o = fopen(out, "w");
    CHECK(in && o);
    char line[4096];
    int most = 0;
    while (in && fgets(line, sizeof line, in))
        if (line_numbers(line) > most) most = line_numbers(line);
    if (in) rewind(in);
    size_t row = 0;
    while (in && o && fgets(line, sizeof line, in))
        if (!(line_numbers(line) == most && row++ == drop)) fputs(line, o);
    if (in) fclose(in);
    if (o) fclose(o);
    return out;
}

/* A scientist's check of the interpolation at the highlight: a sample
 * held out, the table read without it, its value predicted there.  The
 * acrylic's highlight is a plateau 0.75 deg wide (f cos theta_i 3-5 on
 * five samples) that falls 100x by 0.95 deg, narrower than the sample
 * spacing.  The brightest sample, held out, comes back within 25 % in
 * every channel (it came back 3-4x too dark and blue when its off-peak
 * neighbours' colour was spread onto the lobe), and the first sample
 * beside the plateau no more than 3x too bright (12x when the lobe's
 * shape, fitted without it, kept a Beckmann tail there; it comes back a
 * fifth of itself now: where shapes that fit part, the lowest is taken). */
SB_TEST(cornell_highlight_held_out) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    if (sb_test_failed_now()) return;
    sb_measured_info_t info;
    sb_source_t *all = open_table(SB_MEASURED_DIR "/cornell_acryl_blue.brdf", NULL, &info);
    if (!all) return;
    size_t n = sb_source_sample_count(all), top = 0, edge = n;
    double best = 0, th_edge = INFINITY, wi[3], wo[3], f[3], th, td, pd;
    for (size_t k = 0; k < n; k++) /* the brightest in f cos theta_i */
        if (sb_source_sample(all, k, wi, wo, f) && (f[0] + f[1] + f[2]) * wi[2] > best)
            best = (f[0] + f[1] + f[2]) * wi[2], top = k;
    for (size_t k = 0; k < n; k++) /* the nearest the mirror below 1 % of it */
        if (sb_source_sample(all, k, wi, wo, f) && (f[0] + f[1] + f[2]) * wi[2] < 0.01 * best &&
            sb_half_diff_angles(wi, wo, &th, &td, &pd) && th < th_edge)
            th_edge = th, edge = k;
    CHECKF(edge < n && th_edge < 0.02, "no sample beside the highlight (%g rad)", th_edge);
    const size_t rows[2] = {top, edge};
    const double lim[2] = {0.25, 3};
    for (int r = 0; r < 2 && edge < n; r++) {
        sb_source_sample(all, rows[r], wi, wo, f);
        sb_source_t *s = open_table(cornell_without(rows[r], r ? "edge.brdf" : "top.brdf"), NULL, &info);
        double g[3] = {0, 0, 0};
        CHECK(s && sb_source_sample_count(s) == n - 1 && sb_source_eval(s, wi, wo, g) == 1);
        for (int c = 0; c < 3; c++)
            if (r == 0)
                CHECKF(fabs(g[c] - f[c]) <= lim[0] * f[c], "brightest, channel %d: %g for %g", c, g[c], f[c]);
            else
                CHECKF(g[c] <= lim[1] * f[c], "beside it, channel %d: %g for %g", c, g[c], f[c]);
        sb_source_destroy(s);
    }
    sb_source_destroy(all);
}

SB_TEST(alta_shared) {
    CHECKF(has_measured_dir(), "%s: the shipped measured tables are missing", SB_MEASURED_DIR);
    if (sb_test_failed_now()) return;
    sb_measured_info_t info;
    sb_source_t *s = open_table(SB_MEASURED_DIR "/alta_retro-3M-jaune.dat", NULL, &info);
    if (!s) return;
    CHECK(strcmp(info.format, "alta") == 0);
    CHECK(info.rows == 7397);
    CHECK(info.horizon_rows == 86 && info.samples == 7397 - 86);
    CHECK(info.channels == 1);
    CHECK(sb_source_flags(s) & SB_SOURCE_GRAY);
    CHECK(info.value_min[0] > 0 && info.value_max[0] > info.value_min[0]);
    CHECK(info.value_min[0] == info.value_min[2]);
    /* the first row: theta_l 15 deg, theta_v = 90 deg - 2.98 deg, dphi = pi */
    double l[3], v[3], rgb[3];
    sb_dir_from_angles(0.26179938779914940783, 0, l);
    sb_dir_from_angles(1.51843644923506659872, SB_PI, v);
    CHECK(sb_source_eval(s, l, v, rgb) == 1);
    CHECK_REL(rgb[0], 0.00362877 / cos(1.51843644923506659872), 1e-9);
    sb_source_destroy(s);
    /* the other shared files: recognised, not supported */
    expect_fail(SB_MEASURED_DIR "/alta_merl_pink-felt-1d.alta", NULL, SB_ERR_UNSUPPORTED, "#DIM 1 3");
    /* an RGL tensor_file is detected by its magic, whatever its name */
    sb_measured_info_t rinfo;
    sb_source_t *rs = open_table(SB_MEASURED_DIR "/rgl_paper_white_rgb.bsdf", NULL, &rinfo);
    CHECK(rs && strcmp(rinfo.format, "rgl") == 0);
    sb_source_destroy(rs);
}

/* ---- simulated gonioreflectometer --------------------------------------- */

static double rel_frobenius(const sb_matrix_t *a, const sb_matrix_t *b) {
    double num = 0, den = 0;
    for (int c = 0; c < 3; c++)
        for (size_t i = 0; i < a->rows * a->cols; i++) {
            if ((a->mask && !a->mask[i]) || (b->mask && !b->mask[i])) continue;
            double d = a->data[c][i] - b->data[c][i];
            num += d * d;
            den += b->data[c][i] * b->data[c][i];
        }
    return sqrt(num / den);
}

static double rel_frobenius_rank(const sb_factors_t *a, const sb_factors_t *b, size_t n, size_t J) {
    double num = 0, den = 0;
    for (size_t c = 0; c < 3; c++)
        for (size_t col = 0; col < n; col++)
            for (size_t row = 0; row < n; row++) {
                double x = sb_factors_cell(a, J, c, row, col), y = sb_factors_cell(b, J, c, row, col);
                num += (x - y) * (x - y);
                den += y * y;
            }
    return sqrt(num / den);
}

static const char *write_gonio(const char *spec, const sb_gonio_opts_t *go, size_t *rows) {
    const char *path = tmp_path("gonio", "table.csv");
    sb_source_t *m = fx_model(spec);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL);
    sb_result_t r = sb_gonio_write_csv(NULL, fp, m, go, rows);
    CHECK(r == SB_OK);
    fclose(fp);
    sb_source_destroy(m);
    return path;
}

/* 5 deg spacing (18 elevations at 2.5, 7.5, .. 87.5 deg for light and
 * detector, 72 detector azimuths, one light azimuth: isotropy), factored at
 * R = 16, J = 4, against the model factored directly.  Matrices are
 * compared for f and f cos cos; the rank-4 reconstructions for f cos cos
 * only: for f on io the 4th and 5th singular values nearly coincide, so
 * the rank-4 subspace is not determined by the data (two matrices 0.8 %
 * apart give reconstructions 6-15 % apart with the same 81.5 % error). */
SB_TEST(gonio_roundtrip) {
    sb_gonio_opts_t go = {18, 1, 18, 72, 0, 0};
    size_t rows = 0;
    const char *path = write_gonio("microfacet:base=gold,roughness=0.5", &go, &rows);
    CHECK(rows == 18 * 18 * 72);
    sb_measured_info_t info;
    sb_source_t *t = open_table(path, NULL, &info);
    sb_source_t *m = fx_model("microfacet:base=gold,roughness=0.5");
    if (!t) return;
    CHECK(strcmp(info.format, "csv") == 0 && info.rows == rows && info.samples == rows);
    CHECK(sb_source_flags(t) & SB_SOURCE_ISOTROPIC);
    CHECK_REL(info.spacing, 5 * SB_PI / 180, 1e-6);
    sb_param_t *p = NULL;
    sb_param_opts_t po = {0};
    po.res = 16;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK);
    sb_plan_t *plan = NULL;
    sb_plan_opts_t pl = {0};
    pl.terms = 4;
    CHECK(sb_plan_create(NULL, 256, 256, &pl, &plan) == SB_OK);
    for (int form = 0; form < 2; form++) {
        sb_matrix_opts_t mo = {0};
        mo.form = form ? SB_FORM_COS2 : SB_FORM_F;
        sb_matrix_t a, b;
        CHECK(sb_matrix_build(NULL, t, p, &mo, &a) == SB_OK);
        CHECK(sb_matrix_build(NULL, m, p, &mo, &b) == SB_OK);
        CHECK(a.valid_count == 65536); /* full coverage */
        double em = rel_frobenius(&a, &b);
        sb_factors_t *fa = NULL, *fb = NULL;
        CHECK(sb_plan_execute(plan, &a, p, &fa) == SB_OK);
        CHECK(sb_plan_execute(plan, &b, p, &fb) == SB_OK);
        double ea = sb_factors_errors(fa)->rel_rms[3 * 4 + 3], eb = sb_factors_errors(fb)->rel_rms[3 * 4 + 3];
        double er = rel_frobenius_rank(fa, fb, 256, 4);
        printf("form %s: matrices %.3f %%, rank-4 reconstructions %.3f %%, rel_rms %.4f vs %.4f\n", form ? "cos2" : "f",
               100 * em, 100 * er, ea, eb);
        CHECKF(em < 0.02, "matrices differ by %.3f %%", 100 * em);
        CHECKF(fabs(ea - eb) < 0.02, "rel_rms %.4f vs %.4f", ea, eb);
        if (form) CHECKF(er < 0.02, "rank-4 reconstructions differ by %.3f %%", 100 * er);
        sb_factors_destroy(fa);
        sb_factors_destroy(fb);
        sb_matrix_free(&a);
        sb_matrix_free(&b);
    }
    sb_plan_destroy(plan);
    sb_param_destroy(p);
    sb_source_destroy(m);
    sb_source_destroy(t);
}

/* Symmetries and interpolation modes on a simulated table. */
SB_TEST(gonio_symmetry_modes) {
    sb_gonio_opts_t go = {9, 1, 9, 36, 0, 0};
    size_t rows;
    const char *path = write_gonio("microfacet:base=0.7/0.5/0.3,roughness=0.6", &go, &rows);
    sb_source_t *m = fx_model("microfacet:base=0.7/0.5/0.3,roughness=0.6");
    static const sb_interp_t modes[4] = {SB_INTERP_NEAREST, SB_INTERP_IDW, SB_INTERP_LINEAR, SB_INTERP_QUADRATIC};
    for (int k = 0; k < 4; k++) {
        sb_measured_opts_t o = {0};
        o.interp = modes[k];
        sb_measured_info_t info;
        sb_source_t *t = open_table(path, &o, &info);
        if (!t) continue;
        CHECK(info.interp == modes[k] && info.dims == 3);
        unsigned long long seed = 5;
        double worst = 0;
        for (int n = 0; n < 300; n++) {
            double l[3], v[3], a[3], b[3], want[3];
            random_dir(&seed, l);
            random_dir(&seed, v);
            if (l[2] < 0.2 || v[2] < 0.2) continue;
            /* reciprocity and isotropy (a rotation about the normal) */
            double rot = 2 * SB_PI * sb_rand01(&seed), c = cos(rot), s = sin(rot);
            double l2[3] = {c * l[0] - s * l[1], s * l[0] + c * l[1], l[2]};
            double v2[3] = {c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]};
            CHECK(sb_source_eval(t, l, v, a) == 1);
            CHECK(sb_source_eval(t, v2, l2, b) == 1);
            for (int ch = 0; ch < 3; ch++)
                CHECK_REL(a[ch], b[ch], 1e-9);
            sb_source_eval(m, l, v, want);
            double e = fabs(a[1] - want[1]) / want[1];
            if (e > worst) worst = e;
        }
        /* 10 deg spacing: every mode within reach, the fits much closer */
        double lim = modes[k] == SB_INTERP_NEAREST ? 0.5 : modes[k] == SB_INTERP_IDW ? 0.25 : 0.1;
        CHECKF(worst < lim, "%s: worst relative error %.3f", sb_interp_name(modes[k]), worst);
        /* at a measured position every mode returns the sample */
        double l[3], v[3], a[3], want[3];
        sb_dir_from_angles(25 * SB_PI / 180, 0, l);
        sb_dir_from_angles(35 * SB_PI / 180, 40 * SB_PI / 180, v);
        CHECK(sb_source_eval(t, l, v, a) == 1);
        sb_source_eval(m, l, v, want);
        for (int ch = 0; ch < 3; ch++)
            CHECK_REL(a[ch], want[ch], 1e-12);
        sb_source_destroy(t);
    }
    sb_source_destroy(m);
}

/* An anisotropic table (several light azimuths, declared anisotropic). */
SB_TEST(gonio_anisotropic) {
    const char *path = tmp_path("gonio", "aniso.csv");
    sb_source_t *m = fx_model("microfacet:base=0.5,roughness=0.7");
    FILE *fp = fopen(path, "w");
    sb_gonio_opts_t go = {9, 12, 9, 24, 0, 0};
    CHECK(sb_gonio_write_csv(NULL, fp, m, &go, NULL) == SB_OK);
    fclose(fp);
    /* rewrite the symmetry line */
    FILE *in = fopen(path, "r");
    const char *path2 = tmp_path("gonio", "aniso2.csv");
    FILE *out = fopen(path2, "w");
    char line[512];
    while (in && out && fgets(line, sizeof line, in))
        fputs(strcmp(line, "# symmetry: isotropic\n") == 0 ? "# symmetry: anisotropic\n" : line, out);
    if (in) fclose(in);
    if (out) fclose(out);
    sb_measured_info_t info;
    sb_source_t *t = open_table(path2, NULL, &info);
    if (!t) return;
    CHECK(info.dims == 4 && !(sb_source_flags(t) & SB_SOURCE_ISOTROPIC));
    CHECK(sb_source_flags(t) & SB_SOURCE_RECIPROCAL);
    unsigned long long seed = 3;
    double worst = 0, s2 = 0;
    int n = 0;
    for (int it = 0; it < 400; it++) {
        double l[3], v[3], a[3], b[3], want[3];
        random_dir(&seed, l);
        random_dir(&seed, v);
        if (l[2] < 0.3 || v[2] < 0.3) continue;
        CHECK(sb_source_eval(t, l, v, a) == 1);
        CHECK(sb_source_eval(t, v, l, b) == 1);
        for (int ch = 0; ch < 3; ch++)
            CHECK_REL(a[ch], b[ch], 1e-9);
        sb_source_eval(m, l, v, want);
        double e = fabs(a[0] - want[0]) / want[0];
        if (e > worst) worst = e;
        s2 += e * e;
        n++;
    }
    /* 10 deg elevations, light azimuths 30 deg apart, detector 15 deg */
    double rms = sqrt(s2 / n);
    CHECKF(rms < 0.05 && worst < 0.25, "relative error rms %.3f, worst %.3f", rms, worst);
    sb_source_destroy(t);
    sb_source_destroy(m);
}

SB_TEST(gonio_noise_and_ranges) {
    sb_source_t *m = fx_model("lambert:albedo=0.5");
    const char *dir = sb_tmpdir("noise");
    char p[3][4200];
    sb_gonio_opts_t go = {6, 1, 6, 24, 0.1, 7};
    for (int k = 0; k < 3; k++) {
        snprintf(p[k], sizeof p[k], "%s/t%d.csv", dir, k);
        go.seed = k == 2 ? 8 : 7;
        FILE *fp = fopen(p[k], "w");
        size_t rows = 0;
        CHECK(sb_gonio_write_csv(NULL, fp, m, &go, &rows) == SB_OK);
        CHECK(rows == 6 * 6 * 24);
        fclose(fp);
    }
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "cmp -s %s %s", p[0], p[1]);
    CHECK(sb_run(cmd, NULL, 0) == 0); /* same seed, same table */
    snprintf(cmd, sizeof cmd, "cmp -s %s %s", p[0], p[2]);
    CHECK(sb_run(cmd, NULL, 0) != 0);
    /* the noise is multiplicative with sigma 0.1 */
    sb_measured_info_t info;
    sb_measured_opts_t o = {0};
    o.interp = SB_INTERP_NEAREST;
    sb_source_t *t = open_table(p[0], &o, &info);
    if (t) {
        FILE *fp = fopen(p[0], "r");
        char line[512];
        double s1 = 0, s2 = 0;
        int n = 0;
        while (fgets(line, sizeof line, fp)) {
            double a[4], v[3];
            if (sscanf(line, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &a[0], &a[1], &a[2], &a[3], &v[0], &v[1], &v[2]) != 7)
                continue;
            for (int c = 0; c < 3; c++) {
                double z = (v[c] / (0.5 / SB_PI) - 1) / 0.1;
                s1 += z;
                s2 += z * z;
                n++;
            }
        }
        fclose(fp);
        double mean = s1 / n, sd = sqrt(s2 / n - mean * mean);
        CHECKF(fabs(mean) < 0.1 && fabs(sd - 1) < 0.1, "noise mean %g sd %g over %d values", mean, sd, n);
        sb_source_destroy(t);
    }
    /* ranges */
    FILE *fp = fopen("/dev/null", "w");
    sb_context_t *ctx;
    sb_context_create(&ctx);
    sb_gonio_opts_t bad = {6, 0, 6, 24, 0, 0};
    CHECK(sb_gonio_write_csv(ctx, fp, m, &bad, NULL) == SB_ERR_RANGE);
    CHECK(strstr(sb_context_last_error(ctx), "N_phi_i") != NULL);
    sb_gonio_opts_t noisy = {6, 1, 6, 24, -1, 0};
    CHECK(sb_gonio_write_csv(ctx, fp, m, &noisy, NULL) == SB_ERR_RANGE);
    sb_gonio_opts_t huge = {4096, 4096, 4096, 4096, 0, 0};
    CHECK(sb_gonio_write_csv(ctx, fp, m, &huge, NULL) == SB_ERR_OVERFLOW);
    CHECK(sb_gonio_write_csv(ctx, NULL, m, &go, NULL) == SB_ERR_ARG);
    fclose(fp);
    sb_context_destroy(ctx);
    sb_source_destroy(m);
}

/* ---- CSV details, coverage ---------------------------------------------- */

SB_TEST(csv_columns_units) {
    const char *dir = sb_tmpdir("csv");
    char p[4200];
    /* radians by suffix, columns reordered, a mono value, a NaN row */
    snprintf(p, sizeof p, "%s/rad.csv", dir);
    write_text(p, "# a free comment: anything\n"
                  "value, phi_o_rad, theta_o_rad, phi_i_rad, theta_i_rad, extra\n"
                  "0.25, 3.14159265358979, 0.5, 0, 0.5, x\n"
                  "0.5, 0, 0.2, 0, 0.3, y\n"
                  "nan, 0, 0.4, 0, 0.4, z\n"
                  "0.125, 1, 1.5707963267949, 0, 0.3, w\n");
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    if (s) {
        CHECK(info.rows == 4 && info.samples == 2 && info.nan_rows == 1 && info.horizon_rows == 1);
        CHECK(info.channels == 1 && (sb_source_flags(s) & SB_SOURCE_GRAY));
        double l[3], v[3], rgb[3];
        sb_dir_from_angles(0.5, 0, l);
        sb_dir_from_angles(0.5, SB_PI, v);
        CHECK(sb_source_eval(s, l, v, rgb) == 1 && rgb[0] == 0.25 && rgb[2] == 0.25);
        sb_source_destroy(s);
    }
    /* degrees by metadata, RGB, anisotropic by content (phi_i varies) */
    snprintf(p, sizeof p, "%s/deg.csv", dir);
    write_text(p, "# units: degrees\n"
                  "theta_i,phi_i,theta_o,phi_o,r,g,b\n"
                  "30,0,30,180,1,2,3\n"
                  "30,90,30,270,4,5,6\n");
    s = open_table(p, NULL, &info);
    if (s) {
        CHECK(info.dims == 4 && !(sb_source_flags(s) & SB_SOURCE_ISOTROPIC));
        double l[3], v[3], rgb[3];
        sb_dir_from_angles(SB_PI / 6, SB_PI / 2, l);
        sb_dir_from_angles(SB_PI / 6, 1.5 * SB_PI, v);
        CHECK(sb_source_eval(s, l, v, rgb) == 1);
        CHECK_REL(rgb[0], 4, 1e-12);
        CHECK_REL(rgb[2], 6, 1e-12);
        sb_source_destroy(s);
    }
    /* forcing the format: a CSV read as Cornell fails on its first line */
    sb_measured_opts_t o = {0};
    o.format = "cornell";
    expect_fail(p, &o, SB_ERR_FORMAT, ":2: wavelength count");
}

/* Cells farther than the radius from every sample are missing, not
 * invented; a negative radius lifts the limit. */
SB_TEST(coverage_radius) {
    const char *p = tmp_path("cov", "few.csv");
    write_text(p, "theta_i,phi_i,theta_o,phi_o,value\n"
                  "40,0,40,180,1\n"
                  "45,0,40,180,1\n"
                  "40,0,45,170,1\n"
                  "45,0,45,175,1\n");
    sb_param_t *prm = NULL;
    sb_param_opts_t po = {0};
    po.res = 8;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &prm) == SB_OK);
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    size_t known = 0, cells = 0;
    if (s) {
        CHECK(isfinite(info.radius) && info.radius > 0);
        CHECK(sb_measured_coverage(NULL, s, prm, &known, &cells) == SB_OK);
        CHECK(cells == 4096 && known > 0 && known < cells / 10);
        double l[3], v[3], rgb[3];
        sb_dir_from_angles(0.1, 0, l);
        sb_dir_from_angles(1.4, 1, v);
        CHECK(sb_source_eval(s, l, v, rgb) == 0 && rgb[0] == 0);
        sb_source_destroy(s);
    }
    sb_measured_opts_t o = {0};
    o.radius = -1;
    s = open_table(p, &o, &info);
    if (s) {
        CHECK(isinf(info.radius));
        CHECK(sb_measured_coverage(NULL, s, prm, &known, &cells) == SB_OK);
        CHECK(known == cells);
        sb_source_destroy(s);
    }
    /* an analytic source covers everything */
    sb_source_t *m = fx_model("lambert");
    CHECK(sb_measured_coverage(NULL, m, prm, &known, &cells) == SB_OK && known == cells);
    sb_source_destroy(m);
    sb_param_destroy(prm);
}

/* The radius decides alone whether a pair is known: a pair as far as
 * 0.9 of it from the nearest sample is known, one 1.1 of it away is
 * missing although every sample of the row lies within the fits' support
 * (twice the radius) -- the nearest's search bounded by the radius that
 * settles a missing pair before the k-nearest search (scattered_fit.c,
 * has_near) answers as that search did. */
SB_TEST(radius_alone_decides_missing) {
    const char *p = tmp_path("cov", "row.csv");
    FILE *f = fopen(p, "w");
    CHECK(f != NULL);
    if (!f) return;
    fprintf(f, "theta_i,phi_i,theta_o,phi_o,value\n");
    for (int i = 0; i <= 16; i++)
        fprintf(f, "40,0,%g,180,%g\n", 20 + 2.5 * i, 1 + 0.01 * i);
    fclose(f);
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    if (!s) return;
    CHECK(isfinite(info.radius) && info.radius > 0);
    double l[3], v[3], rgb[3];
    sb_dir_from_angles(40 * SB_PI / 180, 0, l);
    for (int side = 0; side < 2; side++) {
        double d = (side ? 1.1 : 0.9) * info.radius; /* off the row along the azimuth difference */
        sb_dir_from_angles(40 * SB_PI / 180, SB_PI - d, v);
        int known = sb_source_eval(s, l, v, rgb);
        CHECKF(side ? known == 0 && rgb[0] == 0 : known != 0 && rgb[0] > 0.9 && rgb[0] < 1.3,
               "%.3g radii from the row: known %d, value %g", side ? 1.1 : 0.9, known, rgb[0]);
    }
    sb_source_destroy(s);
}

/* ---- hostile text ------------------------------------------------------- */

typedef struct hostile {
    const char *name, *text;
    sb_result_t code;
    const char *want;
} hostile_t;

SB_TEST(hostile_text) {
    static const hostile_t cases[] = {
        {"nohead.csv", "1,2,3,4,5\n", SB_ERR_FORMAT, ":1: header lacks column 'theta_i'"},
        {"missingcol.csv", "theta_i,phi_i,theta_o,r,g,b\n1,2,3,4,5,6\n", SB_ERR_FORMAT,
         ":1: header lacks column 'phi_o'"},
        {"short.csv", "theta_i,phi_i,theta_o,phi_o,r,g,b\n10,0,10,180,1,1,1\n10,0,10\n", SB_ERR_FORMAT,
         ":3: 3 fields, the header has 7"},
        {"nanangle.csv", "theta_i,phi_i,theta_o,phi_o,value\n10,0,nan,180,1\n", SB_ERR_FORMAT,
         ":2: theta_o 'nan' is not finite"},
        {"text.csv", "theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,abc\n", SB_ERR_FORMAT,
         ":2: value 'abc' is not a number"},
        {"inf.csv", "theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1e999\n", SB_ERR_FORMAT, ":2: value"},
        {"allnan.csv", "theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,nan\n", SB_ERR_FORMAT, "no usable samples"},
        {"both.csv", "theta_i,phi_i,theta_o,phi_o,r,g,b,value\n", SB_ERR_FORMAT, "either r, g, b or value"},
        {"units.csv", "# units: furlongs\ntheta_i,phi_i,theta_o,phi_o,value\n", SB_ERR_FORMAT, ":1: units"},
        {"empty.csv", "", SB_ERR_FORMAT, "no header"},
        {"neg.brdf", "# num wls\n-5\n", SB_ERR_FORMAT, ":2: wavelength count '-5'"},
        {"huge.brdf", "# num wls\n99999999999999999999\n", SB_ERR_FORMAT, ":2: wavelength count"},
        {"frac.brdf", "# num wls\n2.5\n", SB_ERR_FORMAT, ":2:"},
        {"wls.brdf", "# num wls\n3\n# wls\n400 500 450\n", SB_ERR_FORMAT, ":4: wavelengths not increasing"},
        {"ir.brdf", "# num wls\n2\n# wls\n900 1000\n", SB_ERR_FORMAT, "visible range"},
        {"more.brdf", "# num wls\n2\n# wls\n400\n500 600\n", SB_ERR_FORMAT, ":5: more wavelengths"},
        {"row.brdf", "# num wls\n2\n# wls\n400 500\n0.1 0 0.2 0 0.5\n", SB_ERR_FORMAT, ":5: 5 numbers, expected 6"},
        {"early.brdf", "# num wls\n3\n# wls\n400 500\n", SB_ERR_FORMAT, "ends before the last wavelength"},
        {"garbage.brdf", "# num wls\n2\n# wls\n400 700\n0.1 0 0.2 0 x 1\n", SB_ERR_FORMAT,
         ":5: spectral value 'x' is not a number"},
        {"data.alta", "#DIM 3 1\n0.1 0.2 0.3 0.4\n", SB_ERR_FORMAT, ":2: data before the ALTA header"},
        {"param.alta", "#DIM 3 1\n#PARAM_IN STEREOGRAPHIC\n", SB_ERR_UNSUPPORTED, ":2: ALTA #PARAM_IN STEREOGRAPHIC"},
        {"dims.alta", "#DIM 4 1\n#PARAM_IN RUSIN_TH_TD_PD\n", SB_ERR_FORMAT,
         ":2: #PARAM_IN RUSIN_TH_TD_PD has 3 inputs, #DIM says 4"},
        {"vs.alta", "#DIM 3 1\n#VS 2\n", SB_ERR_UNSUPPORTED, ":2: ALTA confidence"},
        {"cols.alta", "#DIM 3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n#PARAM_OUT INV_STERADIAN\n0.1 0.2 0.3\n",
         SB_ERR_FORMAT, ":4: 3 numbers, expected 4"},
        {"what.txt", "hello world\n", SB_ERR_FORMAT, "unrecognised"},
        /* angles outside their domain, values beyond float storage */
        {"theta1000.csv", "# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1\n1000,0,10,180,1\n",
         SB_ERR_FORMAT, ":4: theta_i '1000' (1000 deg) is outside 0..180 deg"},
        {"theta720.csv", "# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,720,180,1\n", SB_ERR_FORMAT,
         ":3: theta_o '720'"},
        {"thetaneg.csv", "# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n-5,0,10,180,1\n", SB_ERR_FORMAT,
         ":3: theta_i '-5'"},
        {"phi.csv", "# units: degrees\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,10,1e30,1\n", SB_ERR_FORMAT,
         ":3: phi_o '1e30'"},
        {"big.csv", "theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1e308\n10,0,20,180,1e308\n", SB_ERR_FORMAT,
         ":2: f_r = 1e+308 (1/sr) overflows float storage"},
        {"theta100.brdf", "# num wls\n2\n# wls\n400 700\n0.1 0 0.2 0 1 1\n100 0 0.2 0 1 1\n", SB_ERR_FORMAT,
         ":6: theta_i '100'"},
        {"thetav.alta",
         "#DIM 3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n#PARAM_OUT INV_STERADIAN\n0.1 0.2 0.3 0.4\n0.1 1e30 0 1\n",
         SB_ERR_FORMAT, ":5: theta_v cos(dphi) '1e30'"},
        {"thetav2.alta",
         "#DIM 3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n#PARAM_OUT INV_STERADIAN\n0.1 0.2 0.3 0.4\n0.1 3 2 1\n",
         SB_ERR_FORMAT, ":5: theta_v = |(3, 2)|"},
    };
    const char *dir = sb_tmpdir("hostile");
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char p[4200];
        snprintf(p, sizeof p, "%s/%s", dir, cases[k].name);
        write_text(p, cases[k].text);
        expect_fail(p, NULL, cases[k].code, cases[k].want);
    }
    /* NUL bytes, an endless line, a missing file */
    char p[4200];
    snprintf(p, sizeof p, "%s/nul.csv", dir);
    FILE *fp = fopen(p, "wb");
    fputs("theta_i,phi_i,theta_o,phi_o,value\n10,0,", fp);
    fputc(0, fp);
    fputs("10,180,1\n", fp);
    fclose(fp);
    expect_fail(p, NULL, SB_ERR_FORMAT, ":2: binary data");
    snprintf(p, sizeof p, "%s/long.csv", dir);
    fp = fopen(p, "wb");
    fputs("theta_i,phi_i,theta_o,phi_o,value\n", fp);
    for (int i = 0; i < (1 << 21); i++)
        fputc('1', fp);
    fclose(fp);
    expect_fail(p, NULL, SB_ERR_FORMAT, ":2: line longer than");
    snprintf(p, sizeof p, "%s/none.csv", dir);
    expect_fail(p, NULL, SB_ERR_IO, "cannot open");
    /* random bytes with a table's extension never crash */
    unsigned long long seed = 77;
    for (int k = 0; k < 40; k++) {
        static const char *const ext[4] = {"csv", "brdf", "alta", "binary"};
        snprintf(p, sizeof p, "%s/rand%d.%s", dir, k, ext[k % 4]);
        fp = fopen(p, "wb");
        size_t n = (size_t)(sb_rand01(&seed) * 3000);
        for (size_t i = 0; i < n; i++) {
            int c = (int)(sb_rand01(&seed) * 256);
            fputc(k % 2 ? c : "0123456789.,- \n#e"[c % 17], fp);
        }
        fclose(fp);
        sb_context_t *ctx;
        sb_context_create(&ctx);
        sb_source_t *s = NULL;
        sb_result_t r = sb_measured_open(ctx, p, NULL, &s, NULL);
        CHECKF(r != SB_OK || s != NULL, "%s", p);
        if (r != SB_OK) CHECKF(strstr(sb_context_last_error(ctx), p) != NULL, "%s", sb_context_last_error(ctx));
        sb_source_destroy(s);
        sb_context_destroy(ctx);
    }
}

SB_TEST(options_and_names) {
    const char *p = tmp_path("opts", "t.csv");
    write_text(p, "theta_i,phi_i,theta_o,phi_o,value\n10,0,10,180,1\n");
    sb_measured_opts_t o = {0};
    o.neighbours = 65;
    expect_fail(p, &o, SB_ERR_RANGE, "neighbours");
    o.neighbours = 0;
    o.radius = NAN;
    expect_fail(p, &o, SB_ERR_RANGE, "radius");
    o.radius = 0;
    o.interp = (sb_interp_t)99;
    expect_fail(p, &o, SB_ERR_ARG, "interpolation");
    o.interp = SB_INTERP_DEFAULT;
    o.format = "nosuchformat";
    expect_fail(p, &o, SB_ERR_UNKNOWN, "format");
    for (int k = 0; k < SB_INTERP_COUNT_; k++) {
        sb_interp_t m;
        CHECK(sb_interp_parse(sb_interp_name((sb_interp_t)k), &m) == SB_OK && m == (sb_interp_t)k);
    }
    /* the registry: every row named, titled, with an extension; the end is NULL */
    for (size_t k = 0; k < sb_measured_format_count(); k++)
        CHECK(sb_measured_format_name(k) && *sb_measured_format_title(k) && sb_measured_format_exts(k)[0] == '.');
    CHECK(sb_measured_format_name(sb_measured_format_count()) == NULL);
    sb_interp_t m;
    CHECK(sb_interp_parse("cubic", &m) == SB_ERR_UNKNOWN);
    /* one sample: no spacing, so no radius limit */
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    if (s) {
        CHECK(info.spacing == 0 && isinf(info.radius));
        sb_source_destroy(s);
    }
}

/* The example shipped in data/ reads, and the hook opens it. */
SB_TEST(csv_example) {
    sb_measured_info_t info;
    sb_source_t *s = open_table(SB_SOURCE_DIR "/data/example_gonio.csv", NULL, &info);
    if (!s) return;
    CHECK(strcmp(info.format, "csv") == 0 && info.rows == 72 && info.samples == 72 && info.channels == 3);
    sb_source_destroy(s);
    s = NULL;
    CHECK(sb_source_open(NULL, SB_SOURCE_DIR "/data/example_gonio.csv", &s) == SB_OK);
    CHECK(s && strstr(sb_source_description(s), "csv:") == sb_source_description(s));
    sb_source_destroy(s);
}

/* ---- samples and cross-validation ---------------------------------------- */

/* The samples of a table are its rows as read; a model has none.  The
 * default interpolation is the one of lowest cross-validated error, and on
 * a smooth BRDF measured on a 5 deg grid a fit beats the nearest sample
 * (2x on the values as measured);
 * a forced method is kept, its error reported. */
SB_TEST(samples_and_cv) {
    sb_gonio_opts_t go = {0};
    size_t rows = 0;
    const char *p = write_gonio("microfacet:base=gold,roughness=0.5", &go, &rows);
    sb_measured_info_t info;
    sb_source_t *s = open_table(p, NULL, &info);
    if (!s) return;
    CHECK(sb_source_sample_count(s) == rows && rows == 18 * 18 * 72);
    double wi[3], wo[3], f[3], g[3];
    CHECK(sb_source_sample(s, 5, wi, wo, f) == 1 && sb_source_sample(s, rows, wi, wo, f) == 0);
    sb_source_eval(s, wi, wo, g); /* at a measured position: the measurement */
    for (int c = 0; c < 3; c++)
        CHECK_REL(g[c], f[c], 1e-12);
    CHECK(sb_measured_source_info(s) && strcmp(sb_measured_source_info(s)->format, "csv") == 0);
    double best = INFINITY;
    for (int m = SB_INTERP_NEAREST; m < SB_INTERP_COUNT_; m++) {
        CHECKF(isfinite(info.interp_cv[m]) && info.interp_cv[m] > 0, "cv[%d] = %g", m, info.interp_cv[m]);
        best = fmin(best, info.interp_cv[m]);
    }
    CHECK(info.interp_cv[info.interp] == best && info.interp != SB_INTERP_NEAREST);
    CHECK(info.interp_cv[SB_INTERP_NEAREST] > best && info.cv_held_out == 2000);
    sb_source_destroy(s);
    /* relative to the fitted lobe every method is near the lobe's own
     * error; on the values themselves a fit beats the nearest sample 2x */
    sb_measured_opts_t off = {0};
    off.lobe = SB_LOBE_OFF;
    if (!(s = open_table(p, &off, &info))) return;
    best = INFINITY;
    for (int m = SB_INTERP_NEAREST; m < SB_INTERP_COUNT_; m++)
        best = fmin(best, info.interp_cv[m]);
    CHECKF(info.interp_cv[SB_INTERP_NEAREST] > 2 * best, "nearest %g, best %g", info.interp_cv[SB_INTERP_NEAREST],
           best);
    sb_source_destroy(s);
    sb_measured_opts_t o = {0};
    o.interp = SB_INTERP_IDW;
    if ((s = open_table(p, &o, &info))) {
        CHECK(info.interp == SB_INTERP_IDW && isfinite(info.interp_cv[SB_INTERP_IDW]));
        sb_source_destroy(s);
    }
    /* a model has no samples: no error against them */
    sb_source_t *m = fx_model("lambert");
    CHECK(sb_source_sample_count(m) == 0 && sb_measured_source_info(m) == NULL);
    sb_sample_errors_t se;
    CHECK(sb_measured_sample_errors(NULL, m, NULL, NULL, SB_FORM_F, &se) == SB_ERR_ARG);
    sb_source_destroy(m);
}

/* The lobe a scattered table is interpolated relative to: on a table of a
 * Cook-Torrance model inside the lobe's family (GGX, Smith-Schlick with
 * the remapped k, Schlick F0 0.04) the fit recovers the model's shape, and
 * the table relative to it predicts the model between the samples far
 * better than the values interpolated as they are. */
static double table_vs_model(sb_source_t *t, sb_source_t *m) {
    unsigned long long seed = 7;
    double num = 0, den = 0;
    for (int k = 0; k < 20000; k++) {
        double l[3], v[3], a[3], b[3];
        random_dir(&seed, l);
        random_dir(&seed, v);
        if (l[2] < 0.05 || v[2] < 0.05 || !sb_source_eval(t, l, v, a)) continue;
        sb_source_eval(m, l, v, b);
        for (int c = 0; c < 3; c++)
            num += (a[c] - b[c]) * (a[c] - b[c]) * l[2] * l[2], den += b[c] * b[c] * l[2] * l[2];
    }
    return sqrt(num / den);
}

SB_TEST(lobe_recovers_model) {
    const char *spec = "cook-torrance:d=ggx,roughness=0.3";
    sb_gonio_opts_t go = {12, 1, 12, 48, 0, 0};
    size_t rows = 0;
    const char *p = write_gonio(spec, &go, &rows);
    sb_measured_opts_t o = {0};
    sb_measured_info_t on, off;
    o.lobe = SB_LOBE_ON;
    sb_source_t *t = open_table(p, &o, &on), *m = fx_model(spec);
    o.lobe = SB_LOBE_OFF;
    sb_source_t *u = open_table(p, &o, &off);
    if (!t || !u || !m) return;
    const sb_lobe_fit_t *L = &on.lobe;
    CHECKF(L->fitted && L->used && strcmp(L->ndf, "ggx") == 0 && L->f0 == 0.04 && L->cos_power == 1 &&
               L->smith_k_remapped,
           "%s f0 %g p %g remapped %d", L->ndf, L->f0, L->cos_power, L->smith_k_remapped);
    CHECK_REL(L->alpha, 0.09, 0.02);
    CHECK(!off.lobe.fitted && !off.lobe.used);
    double e_on = table_vs_model(t, m), e_off = table_vs_model(u, m);
    printf("between the samples: %.4f with the lobe, %.4f without; interp cv %.4f vs %.4f\n", e_on, e_off, L->cv_on,
           off.lobe.cv_off);
    CHECKF(e_on < e_off / 3, "with the lobe %g, without %g", e_on, e_off);
    /* auto keeps the lobe where it lowers the cross-validated error */
    sb_measured_info_t au;
    o.lobe = SB_LOBE_AUTO;
    sb_source_t *a = open_table(p, &o, &au);
    CHECK(a && au.lobe.used == (au.lobe.cv_on < 0.9 * au.lobe.cv_off) && au.lobe.used);
    sb_source_destroy(a);
    /* a measured position still returns its measurement */
    double wi[3], wo[3], f[3], g[3];
    CHECK(sb_source_sample(t, 17, wi, wo, f) == 1 && sb_source_eval(t, wi, wo, g) == 1);
    for (int c = 0; c < 3; c++)
        CHECK(g[c] == f[c]);
    sb_source_destroy(t);
    sb_source_destroy(u);
    sb_source_destroy(m);
}

/* A glossy table whose lobe family is exact (GGX, Schlick, Lambert) keeps
 * the model's peak where no sample is: beyond its last elevation (82.5
 * deg) the mirror peak grows as F G / cos, and a cap on f (2x the
 * brightest sample) clipped it there, a non-separable plateau that cost
 * its 4-term fit 17 % in the retro band.  The cap bounds the lobe's D
 * instead (docs/measured.md). */
SB_TEST(lobe_keeps_grazing_peak) {
    const char *spec = "cook-torrance:kd=0.5,ks=0.5,albedo=0.8/0.15/0.08,roughness=0.15";
    sb_gonio_opts_t go = {6, 1, 12, 24, 0, 0};
    size_t rows = 0;
    const char *p = write_gonio(spec, &go, &rows);
    sb_measured_opts_t o = {0};
    sb_measured_info_t in;
    o.lobe = SB_LOBE_ON;
    sb_source_t *t = open_table(p, &o, &in), *m = fx_model(spec);
    if (!t || !m) return;
    CHECKF(in.lobe.fitted && strcmp(in.lobe.ndf, "ggx") == 0, "%s", in.lobe.ndf);
    CHECK(in.lobe.d_cap > 0 && isfinite(in.lobe.d_cap));
    double worst = 0;
    for (double th = 84; th < 89.6; th += 0.5) { /* the mirror pair, beyond every sample's elevation */
        double l[3], v[3], a[3], b[3], r = th * SB_PI / 180;
        l[0] = sin(r), l[1] = 0, l[2] = cos(r), v[0] = -l[0], v[1] = 0, v[2] = l[2];
        CHECK(sb_source_eval(t, l, v, a) == 1 && sb_source_eval(m, l, v, b) == 1);
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(a[c] - b[c]) / b[c]);
    }
    CHECKF(worst < 1e-3, "table off the model by %g on the grazing mirror peak", worst);
    double e = table_vs_model(t, m);
    CHECKF(e < 1e-3, "table vs model between the samples: %g", e);
    sb_source_destroy(t);
    sb_source_destroy(m);
}

/* A clean table of a material the lobe's families hold (GGX alpha 0.3,
 * 1536 rows, a Cornell paint's count) predicts a grazing mirror row it
 * does not hold: the row held out, the lobe fitted to the others and the
 * table's value there within 5 % of the model.  The base took the lowest
 * of the shapes within 1 of the best cost, shapes 17-32 % worse than it
 * here (0.53, 0.60 against 0.45): the rows came back 10-20 % low, and a
 * random split holding one erred 4-13x the reported figure
 * (docs/measured.md, "Random splits against the reported figure"). */
/* Each mirror row theta = (k + 0.5) 90 / 8 deg for k in [k0, k1) of a
 * table of spec sampled at --gonio 8,1,8,24, held out alone (or all of
 * them together: `together`): the lobe fitted to the others and the
 * table's value there, every channel, within tol of the model. */
static void held_out_mirror(const char *spec, int k0, int k1, double tol, int together) {
    sb_gonio_opts_t go = {8, 1, 8, 24, 0, 0};
    size_t rows = 0;
    const char *p = write_gonio(spec, &go, &rows);
    sb_source_t *m = fx_model(spec);
    char held[4096];
    snprintf(held, sizeof held, "%s", tmp_path("gonio", "held.csv"));
    for (int k = k0; k < k1 && m; k++) {
        double th = (k + 0.5) * 90.0 / 8, a, b, c, d, l[3], v[3], f[3], g[3];
        int lo = together ? k0 : k, hi = together ? k1 : k + 1; /* the rows left out */
        FILE *in = fopen(p, "r"), *out = fopen(held, "w");
        CHECK(in && out);
        if (!in || !out) break;
        char line[512];
        int dropped = 0;
        while (fgets(line, sizeof line, in)) {
            int row = sscanf(line, "%lf,%lf,%lf,%lf", &a, &b, &c, &d) == 4;
            double ka = a * 8 / 90 - 0.5; /* the row's elevation index */
            if (row && fabs(ka - floor(ka + 0.5)) < 1e-6 && ka > lo - 0.5 && ka < hi - 0.5 && fabs(a - c) < 1e-6 &&
                fabs(fabs(d - b) - 180) < 1e-6) {
                dropped++;
                continue;
            }
            fputs(line, out);
        }
        fclose(in);
        fclose(out);
        CHECKF(dropped == hi - lo, "theta %g: %d mirror rows", th, dropped);
        sb_measured_info_t info;
        sb_source_t *t = open_table(held, NULL, &info);
        if (!t) break;
        double r = th * SB_PI / 180;
        l[0] = sin(r), l[1] = 0, l[2] = cos(r), v[0] = -l[0], v[1] = 0, v[2] = l[2];
        CHECK(info.lobe.used && sb_source_eval(t, l, v, f) == 1 && sb_source_eval(m, l, v, g) == 1);
        printf("%s: mirror row at %.1f deg held out: table (%.4f %.4f %.4f), model (%.4f %.4f %.4f)\n", spec, th, f[0],
               f[1], f[2], g[0], g[1], g[2]);
        for (int ch = 0; ch < 3; ch++)
            CHECKF(fabs(f[ch] - g[ch]) < tol * g[ch], "theta %.1f channel %d: table %g, model %g", th, ch, f[ch],
                   g[ch]);
        sb_source_destroy(t);
    }
    sb_source_destroy(m);
}

SB_TEST(lobe_predicts_held_out_mirror) {
    held_out_mirror("microfacet:roughness=0.548", 5, 8, 0.05, 0); /* theta 61.9, 73.1, 84.4 deg */
}

/* The grazing mirror rows of a glossy table held out together (as a
 * random split holding two of them does): the microfacet model's diffuse
 * (1 - F) base / pi falls towards grazing, which a constant kd could not
 * follow (the lobe fitted GGX alpha 0.286 for 0.3 and the rows came back
 * 4-7 % low: splits holding them erred 3-11x the reported figure).  With
 * the diffuse factor 1 - (1 - v.h)^5 among the lobe's families they are
 * within 1 %. */
SB_TEST(lobe_predicts_grazing_mirror_rows_together) {
    held_out_mirror("microfacet:roughness=0.548", 5, 8, 0.01, 1);
    held_out_mirror("microfacet:roughness=0.316", 5, 8, 0.01, 1);
}

/* A coloured metal's highlight whitens towards grazing (Schlick's F per
 * channel: gold's blue F0 0.34 rises to 1).  The lobe's one grey F0 kept
 * the highlight's colour at every angle: gold's grazing mirror rows, held
 * out alone, came back 12 % (73.1 deg) and 43 % (84.4 deg) low in blue,
 * and random splits holding them erred 3x the reported figure
 * (docs/measured.md, "Random splits against the reported figure").  With
 * an F0 per channel they are within 5 % in every channel. */
SB_TEST(lobe_predicts_coloured_grazing_mirror) {
    held_out_mirror("microfacet:base=gold,roughness=0.4", 6, 8, 0.05, 0); /* theta 73.1, 84.4 deg */
    sb_measured_info_t info;
    sb_gonio_opts_t go = {8, 1, 8, 24, 0, 0};
    size_t rows = 0;
    sb_source_t *t = open_table(write_gonio("microfacet:base=gold,roughness=0.4", &go, &rows), NULL, &info);
    const sb_lobe_fit_t *L = &info.lobe;
    CHECKF(t && L->f0_per_channel && L->f0_rgb[0] > L->f0_rgb[1] && L->f0_rgb[1] > L->f0_rgb[2],
           "F0 per channel %d (%g %g %g)", L->f0_per_channel, L->f0_rgb[0], L->f0_rgb[1], L->f0_rgb[2]);
    sb_source_destroy(t);
}

/* MERL samples: every measured cell at its centre, missing cells not. */
SB_TEST(merl_samples) {
    const char *p = tmp_path("merl", "idx.binary");
    write_merl_raw(p, merl_dims, 3 * (size_t)NCELLS, index_value, 0);
    sb_source_t *s = open_table(p, NULL, NULL);
    if (!s) return;
    CHECK(sb_source_sample_count(s) == NCELLS);
    double wi[3], wo[3], f[3];
    CHECK(sb_source_sample(s, 7, wi, wo, f) == 0); /* missing */
    size_t k = 90 * 180 * 40 + 180 * 20 + 33;      /* theta_h 40, theta_d 20, phi_d 33 */
    CHECK(sb_source_sample(s, k, wi, wo, f) == 1);
    CHECK_REL(f[1], (double)(k + 1) * scale[1], 1e-12);
    size_t idx;
    CHECK(sb_merl_index(wi, wo, &idx) && idx == k);
    sb_source_destroy(s);
}

/* ---- gamut -------------------------------------------------------------------- */

/* keep leaves the value, clip zeroes the negatives, desaturate keeps the
 * luminance and the hue (the direction from gray) and ends on the gamut
 * boundary; inside the gamut nothing changes. */
SB_TEST(gamut_map) {
    double in[3] = {-0.1, 0.5, 0.2}, v[3];
    memcpy(v, in, sizeof v);
    CHECK(sb_gamut_map(SB_GAMUT_KEEP, v) == 1 && memcmp(v, in, sizeof v) == 0);
    CHECK(sb_gamut_map(SB_GAMUT_CLIP, v) == 1 && v[0] == 0 && v[1] == 0.5 && v[2] == 0.2);
    memcpy(v, in, sizeof v);
    CHECK(sb_gamut_map(SB_GAMUT_DESATURATE, v) == 1);
    double y0 = 0.2126 * in[0] + 0.7152 * in[1] + 0.0722 * in[2], y1 = 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    CHECK_REL(y1, y0, 1e-12);
    CHECK(fabs(v[0]) < 1e-15 && v[1] >= 0 && v[2] >= 0);
    CHECK_REL((v[1] - y0) / (in[1] - y0), (v[2] - y0) / (in[2] - y0), 1e-12); /* same hue */
    double neg_y[3] = {-0.5, 0.01, 0.01};
    CHECK(sb_gamut_map(SB_GAMUT_DESATURATE, neg_y) == 1 && neg_y[0] == 0 && neg_y[1] == 0 && neg_y[2] == 0);
    double ok[3] = {0.1, 0.2, 0.3};
    CHECK(sb_gamut_map(SB_GAMUT_DESATURATE, ok) == 0 && ok[0] == 0.1 && ok[2] == 0.3);
    sb_gamut_t g;
    CHECK(sb_gamut_parse("desaturate", &g) == SB_OK && g == SB_GAMUT_DESATURATE);
    CHECK(sb_gamut_parse("purple", &g) == SB_ERR_UNKNOWN && strcmp(sb_gamut_name(SB_GAMUT_CLIP), "clip") == 0);
}

/* The shared acrylic: 1364 of 1439 rows out of gamut whatever is done with
 * them; clip and desaturate leave no negative sample, desaturate keeps
 * each sample's luminance. */
SB_TEST(gamut_cornell) {
    const char *p = SB_MEASURED_DIR "/cornell_acryl_blue.brdf";
    sb_measured_opts_t o = {0};
    sb_measured_info_t info;
    sb_source_t *keep = open_table(p, &o, &info);
    CHECK(info.out_of_gamut == 1364 && info.gamut == SB_GAMUT_KEEP && info.value_min[1] < 0);
    for (int mode = SB_GAMUT_CLIP; mode <= SB_GAMUT_DESATURATE; mode++) {
        o.gamut = (sb_gamut_t)mode;
        sb_source_t *s = open_table(p, &o, &info);
        if (!s || !keep) continue;
        CHECK(info.out_of_gamut == 1364 && info.gamut == (sb_gamut_t)mode);
        size_t neg = 0, lum = 0;
        for (size_t k = 0; k < sb_source_sample_count(s); k++) {
            double wi[3], wo[3], a[3], b[3];
            sb_source_sample(s, k, wi, wo, a);
            sb_source_sample(keep, k, wi, wo, b);
            neg += a[0] < 0 || a[1] < 0 || a[2] < 0;
            double ya = 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2],
                   yb = 0.2126 * b[0] + 0.7152 * b[1] + 0.0722 * b[2];
            lum += yb > 0 && fabs(ya - yb) > 1e-12 * fabs(yb);
        }
        CHECK(neg == 0);
        if (mode == SB_GAMUT_DESATURATE) CHECKF(lum == 0, "%zu samples changed luminance", lum);
        sb_source_destroy(s);
    }
    sb_source_destroy(keep);
}

/* ---- unmeasured regions -------------------------------------------------------- */

/* Light or view along the normal: every azimuth is known (no black
 * pinholes), within the range of the measured values; exactly at the pole
 * the value does not depend on the azimuth. */
SB_TEST(pole_no_pinholes) {
    sb_measured_info_t info;
    sb_source_t *s = open_table(SB_MEASURED_DIR "/cornell_acryl_blue.brdf", NULL, &info);
    if (!s) return;
    size_t missing = 0, out = 0;
    double first[3] = {0, 0, 0};
    for (int a = 1; a <= 7; a++)
        for (int b = 0; b < 36; b++) {
            double t = a * 10 * SB_PI / 180, p = b * 10 * SB_PI / 180, rgb[3];
            double l[3] = {sin(t) * cos(p), sin(t) * sin(p), cos(t)}, n[3] = {0, 0, 1};
            for (int swap = 0; swap < 2; swap++) {
                if (!sb_source_eval(s, swap ? n : l, swap ? l : n, rgb)) {
                    missing++;
                    continue;
                }
                for (int c = 0; c < 3; c++)
                    out += rgb[c] < info.value_min[c] - 1e-12 || rgb[c] > info.value_max[c] + 1e-12;
            }
        }
    CHECKF(missing == 0 && out == 0, "%zu missing, %zu out of range", missing, out);
    /* at an elevation not measured with the view along the normal: the
     * azimuthal mean, the same for every azimuth */
    for (int b = 0; b < 36; b++) {
        double t = 35 * SB_PI / 180, p = b * 10 * SB_PI / 180, rgb[3];
        double l[3] = {sin(t) * cos(p), sin(t) * sin(p), cos(t)}, n[3] = {0, 0, 1};
        CHECK(sb_source_eval(s, l, n, rgb) == 1);
        if (b == 0) memcpy(first, rgb, sizeof first);
        for (int c = 0; c < 3; c++)
            CHECK_REL(rgb[c], first[c], 1e-9);
    }
    sb_source_destroy(s);
}

/* A value of the interpolated table is a function of the pair alone: the
 * same bits whatever was asked before (the search starts from the previous
 * query's neighbours, the table remembers values by position), at random
 * pairs asked forward on one table, backward on a second, and again. */
SB_TEST(value_independent_of_history) {
    const char *path = SB_MEASURED_DIR "/cornell_acryl_blue.brdf";
    sb_source_t *a = open_table(path, NULL, NULL), *b = open_table(path, NULL, NULL);
    enum { N = 3000 };
    static double wi[N][3], wo[N][3], va[N][3], vb[N][3], vc[N][3];
    int ka[N], kb[N], kc[N];
    if (!a || !b) goto done;
    uint64_t st = 42;
#define NEXT (st = st * 6364136223846793005ull + 1442695040888963407ull, st >> 33)
    for (int i = 0; i < N; i++) {
        /* clustered: pairs near each other, as a matrix row asks them */
        double ti = (i / 50) * 0.026 + 0.001 * (double)(NEXT % 100), to = 0.4 + 0.002 * (i % 50);
        double pi_ = 0.01 * (double)(NEXT % 628), po = pi_ + 0.05 * (double)(i % 7);
        sb_dir_from_angles(ti, pi_, wi[i]);
        sb_dir_from_angles(to, po, wo[i]);
    }
#undef NEXT
    for (int i = 0; i < N; i++)
        ka[i] = sb_source_eval(a, wi[i], wo[i], va[i]);
    for (int i = N - 1; i >= 0; i--)
        kb[i] = sb_source_eval(b, wi[i], wo[i], vb[i]);
    for (int i = 0; i < N; i++)
        kc[i] = sb_source_eval(a, wi[i], wo[i], vc[i]);
    size_t differ = 0, known = 0;
    for (int i = 0; i < N; i++) {
        known += ka[i] != 0;
        differ += ka[i] != kb[i] || ka[i] != kc[i] || memcmp(va[i], vb[i], sizeof va[i]) != 0 ||
                  memcmp(va[i], vc[i], sizeof va[i]) != 0;
    }
    CHECKF(differ == 0 && known > N / 2, "%zu of %d pairs differ (%zu known)", differ, N, known);
done:
    sb_source_destroy(a);
    sb_source_destroy(b);
}

/* The coverage map sums to the coverage; a table measured everywhere is
 * known in every band, the 3M tape (four light elevations) is not. */
SB_TEST(coverage_map) {
    sb_param_opts_t po = {0};
    po.res = 12;
    sb_param_t *p = NULL;
    CHECK(sb_param_create(NULL, SB_PARAM_IO, &po, &p) == SB_OK);
    sb_gonio_opts_t go = {0};
    const char *files[2] = {write_gonio("lambert", &go, NULL), SB_MEASURED_DIR "/alta_retro-3M-jaune.dat"};
    for (int f = 0; f < 2 && p; f++) {
        sb_source_t *s = open_table(files[f], NULL, NULL);
        if (!s) continue;
        size_t known[9], cells[9], k = 0, n = 0, tk = 0, tn = 0, full = 0;
        CHECK(sb_measured_coverage_map(NULL, s, p, 3, known, cells) == SB_OK);
        CHECK(sb_measured_coverage(NULL, s, p, &tk, &tn) == SB_OK);
        for (int b = 0; b < 9; b++) {
            k += known[b];
            n += cells[b];
            full += known[b] == cells[b];
            CHECK(cells[b] == 48 * 48); /* (4 elevations x 12 azimuths) per direction */
        }
        CHECK(k == tk && n == tn && n == 144 * 144);
        CHECK(f == 0 ? full == 9 : full < 9);
        sb_source_destroy(s);
    }
    size_t a, b;
    CHECK(sb_measured_coverage_map(NULL, NULL, p, 3, &a, &b) == SB_ERR_ARG);
    sb_param_destroy(p);
}

/* ---- ALTA parameterisations ------------------------------------------------ */

/* A smooth reciprocal function (the reader takes ALTA tables as
 * reciprocal) that depends on the azimuth difference through wi . wo. */
static double alta_g(const double wi[3], const double wo[3]) {
    return 0.2 + 0.15 * (wi[2] * wi[2] + wo[2] * wo[2]) + 0.1 * (wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]);
}
/* The same plus a reciprocal anisotropic term (a wrong sign of phi moves it). */
static double alta_ga(const double wi[3], const double wo[3]) {
    double s = wi[0] + wi[1] + wo[0] + wo[1];
    return alta_g(wi, wo) + 0.1 * s * s;
}

/* The row inputs of pair (l = wi, v = wo) under ALTA parameterisation
 * `name`, by independent formulas (Rusinkiewicz by the rotation matrices
 * of ref_index, unfolded); the count. */
static int alta_inputs(const char *name, const double l[3], const double v[3], double *a) {
    double tl = acos(l[2]), pl = atan2(l[1], l[0]), tv = acos(v[2]), pv = atan2(v[1], v[0]);
    if (strcmp(name, "ISOTROPIC_TL_TV_PROJ_DPHI") == 0) {
        a[0] = tl, a[1] = tv * cos(pv - pl), a[2] = tv * sin(pv - pl);
        return 3;
    }
    if (strcmp(name, "ISOTROPIC_TV_TL_DPHI") == 0) {
        double dp = remainder(pv - pl, 2 * SB_PI);
        a[0] = tv, a[1] = tl, a[2] = dp;
        return 3;
    }
    if (strcmp(name, "SPHERICAL_TL_PL_TV_PV") == 0) {
        a[0] = tl, a[1] = pl, a[2] = tv, a[3] = pv;
        return 4;
    }
    if (strcmp(name, "CARTESIAN") == 0) {
        for (int k = 0; k < 3; k++)
            a[k] = l[k], a[3 + k] = v[k];
        return 6;
    }
    double r[4];
    ref_halfdiff(l, v, r);
    if (strcmp(name, "RUSIN_TH_TD_PD") == 0) { /* isotropic: phi_h dropped */
        a[0] = r[0], a[1] = r[2], a[2] = r[3];
        return 3;
    }
    memcpy(a, r, sizeof r); /* RUSIN_TH_PH_TD_PD */
    return 4;
}

/* Every ALTA #PARAM_IN read: a table of alta_g written in it (rows at
 * pairs of our own; isotropic layouts get pairs with phi_l = 0, the others
 * any azimuth; INV_STERADIAN_COSINE_FACTOR, f cos(theta_v), in one of them:
 * the view direction must be wo) reads back as the same function at pairs
 * between the rows, so each layout's angles are as ALTA defines them (a
 * wrong sign of an azimuth moves wi . wo, the cosine of the wrong
 * direction scales f by cos(theta_l) / cos(theta_v)). */
SB_TEST(alta_parameterisations) {
    static const char *const names[] = {"ISOTROPIC_TL_TV_PROJ_DPHI", "ISOTROPIC_TV_TL_DPHI",  "RUSIN_TH_TD_PD",
                                        "RUSIN_TH_PH_TD_PD",         "SPHERICAL_TL_PL_TV_PV", "CARTESIAN"};
    for (size_t k = 0; k < sizeof names / sizeof *names; k++) {
        int iso = k < 3, cosine = k == 1;
        const char *path = tmp_path("alta_params", "table.alta");
        FILE *fp = fopen(path, "w");
        CHECK(fp != NULL);
        if (!fp) return;
        double a[6];
        double l0[3] = {0, 0, 1};
        int din = alta_inputs(names[k], l0, l0, a);
        fprintf(fp, "#DIM %d 1\n#PARAM_IN %s\n#PARAM_OUT %s\n", din, names[k],
                cosine ? "INV_STERADIAN_COSINE_FACTOR" : "INV_STERADIAN");
        uint64_t seed = 11 + k;
        size_t rows = 0;
        for (int it = 0; it < 14; it++)
            for (int ip = 0; ip < (iso ? 1 : 12); ip++)
                for (int ot = 0; ot < 14; ot++)
                    for (int op = 0; op < 24; op++) {
                        double l[3], v[3];
                        double pl = iso ? 0 : 2 * SB_PI * (ip + 0.5) / 12;
                        sb_dir_from_angles((it + 0.5) / 14 * SB_PI / 2 * 0.98, pl, l);
                        sb_dir_from_angles((ot + 0.5) / 14 * SB_PI / 2 * 0.98, pl + 2 * SB_PI * (op + 0.5) / 24, v);
                        int n = alta_inputs(names[k], l, v, a);
                        for (int c = 0; c < n; c++)
                            fprintf(fp, "%.17g ", a[c]);
                        fprintf(fp, "%.17g\n", (iso ? alta_g(l, v) : alta_ga(l, v)) * (cosine ? v[2] : 1));
                        rows++;
                    }
        (void)seed;
        fclose(fp);
        sb_measured_info_t info;
        sb_source_t *s = open_table(path, NULL, &info);
        CHECK(s != NULL);
        if (!s) continue;
        CHECKF(info.samples == rows, "%s: %zu samples of %zu rows", names[k], info.samples, rows);
        CHECKF(((sb_source_flags(s) & SB_SOURCE_ISOTROPIC) != 0) == iso, "%s: isotropic %d", names[k], iso);
        double worst = 0, node = 0;
        for (int t = 0; t < 200; t++) { /* pairs between the rows, away from the table's edges */
            double l[3], v[3], rgb[3];
            sb_dir_from_angles((0.1 + 0.7 * fmod(t * 0.618034, 1)) * SB_PI / 2,
                               iso ? 0 : fmod(t * 0.3819, 1) * 2 * SB_PI, l);
            sb_dir_from_angles((0.1 + 0.7 * fmod(t * 0.7548, 1)) * SB_PI / 2, fmod(t * 0.5698, 1) * 2 * SB_PI, v);
            if (sb_source_eval(s, l, v, rgb))
                worst = fmax(worst, fabs(rgb[0] / (iso ? alta_g(l, v) : alta_ga(l, v)) - 1));
            /* and at a row's own pair (inside the grid) */
            int it = 1 + t % 12, ip = iso ? 0 : t % 12, ot = 1 + (t * 7) % 12, op = (t * 5) % 24;
            double pl = iso ? 0 : 2 * SB_PI * (ip + 0.5) / 12;
            sb_dir_from_angles((it + 0.5) / 14 * SB_PI / 2 * 0.98, pl, l);
            sb_dir_from_angles((ot + 0.5) / 14 * SB_PI / 2 * 0.98, pl + 2 * SB_PI * (op + 0.5) / 24, v);
            if (sb_source_eval(s, l, v, rgb))
                node = fmax(node, fabs(rgb[0] / (iso ? alta_g(l, v) : alta_ga(l, v)) - 1));
        }
        printf("  %-26s %zu rows, worst relative error at rows %.2e, between them %.2e\n", names[k], rows, node, worst);
        CHECKF(node < 0.01, "%s: at the rows %.3g", names[k], node);
        CHECKF(worst < (iso ? 0.03 : 0.15), "%s: between the rows %.3g", names[k], worst);
        sb_source_destroy(s);
    }
}

/* A scattered table is the same table whatever the order of its rows: the
 * ALTA retro table with its data rows reversed gives the same samples (in
 * the table's order), the same interpolation, lobe and cross-validation,
 * and the same values (the held-out rows of the cross-validation, the
 * folds of cv_headline and the lobe's subsample were taken by row index:
 * shuffled, the table chose quadratic over nearest and factor's headline
 * read 0.118 against 0.218). */
SB_TEST(row_order_independent) {
    const char *src = SB_MEASURED_DIR "/alta_retro-3M-jaune.dat", *rev = tmp_path("row_order", "reversed.dat");
    FILE *in = fopen(src, "r"), *out = fopen(rev, "w");
    CHECK(in != NULL && out != NULL);
    if (!in || !out) return;
    static char lines[8192][160];
    size_t n = 0;
    char buf[512];
    while (fgets(buf, sizeof buf, in)) {
        if (buf[0] == '#' || buf[0] == '\n')
            fputs(buf, out);
        else if (n < 8192 && strlen(buf) < sizeof lines[0])
            memcpy(lines[n++], buf, strlen(buf) + 1);
    }
    for (size_t i = n; i-- > 0;)
        fputs(lines[i], out);
    fclose(in);
    fclose(out);
    CHECKF(n > 7000, "%zu rows", n);
    sb_measured_info_t a, b;
    sb_source_t *s = open_table(src, NULL, &a), *t = open_table(rev, NULL, &b);
    CHECK(s != NULL && t != NULL);
    if (!s || !t) {
        sb_source_destroy(s);
        sb_source_destroy(t);
        return;
    }
    CHECKF(a.samples == b.samples && a.interp == b.interp, "samples %zu / %zu, interp %s / %s", a.samples, b.samples,
           sb_interp_name(a.interp), sb_interp_name(b.interp));
    for (int m = 0; m < SB_INTERP_COUNT_; m++)
        CHECKF(a.interp_cv[m] == b.interp_cv[m] || (isnan(a.interp_cv[m]) && isnan(b.interp_cv[m])),
               "interp cv %d: %.6g / %.6g", m, a.interp_cv[m], b.interp_cv[m]);
    CHECKF(a.lobe.alpha == b.lobe.alpha, "lobe alpha %.6g / %.6g", a.lobe.alpha, b.lobe.alpha);
    size_t differ = 0;
    for (size_t i = 0; i < a.samples; i++) {
        double wi[3], wo[3], f[3], wi2[3], wo2[3], f2[3];
        sb_source_sample(s, i, wi, wo, f);
        sb_source_sample(t, i, wi2, wo2, f2);
        differ += memcmp(wi, wi2, sizeof wi) || memcmp(wo, wo2, sizeof wo) || memcmp(f, f2, sizeof f);
    }
    CHECKF(differ == 0, "%zu of %zu samples numbered differently", differ, a.samples);
    for (int k = 0; k < 100; k++) {
        double l[3], v[3], x[3] = {0}, y[3] = {0};
        sb_dir_from_angles(fmod(k * 0.618034, 1) * 1.0, 0, l);
        sb_dir_from_angles(fmod(k * 0.7548, 1) * 1.4, fmod(k * 0.5698, 1) * 2 * SB_PI, v);
        int kx = sb_source_eval(s, l, v, x), ky = sb_source_eval(t, l, v, y);
        CHECKF(kx == ky && x[0] == y[0], "pair %d: %.9g / %.9g", k, x[0], y[0]);
    }
    printf("  %zu rows reversed: interp %s, cv %.4g, same samples and values\n", n, sb_interp_name(a.interp),
           a.interp_cv[a.interp]);
    sb_source_destroy(s);
    sb_source_destroy(t);
}

/* An isotropic, reciprocal table's value is a function of the embedded
 * position: a pair, the pair rotated about the normal and the pair swapped
 * give the same bits.  Their embeddings differ in the last places (the
 * rotation's arithmetic), and before positions were rounded
 * (scattered_fit.c, POSITION_GRID) their values did too, so that the memo
 * missed the cells of a layout (hd) whose pairs fold onto one position. */
SB_TEST(rotated_pairs_same_value) {
    sb_measured_info_t info;
    sb_source_t *s = open_table(SB_MEASURED_DIR "/cornell_acryl_blue.brdf", NULL, &info);
    CHECK(s != NULL);
    if (!s) return;
    size_t known = 0, differ = 0;
    for (int k = 0; k < 400; k++) {
        double l[3], v[3], x[3], y[3], z[3], rl[3], rv[3];
        double ti = fmod(k * 0.618034, 1) * 1.3, to = fmod(k * 0.7548, 1) * 1.3, dp = fmod(k * 0.5698, 1) * 2 * SB_PI;
        double rot = 0.1 + fmod(k * 0.3819, 1) * 2 * SB_PI; /* the pair turned about the normal */
        sb_dir_from_angles(ti, 0, l);
        sb_dir_from_angles(to, dp, v);
        sb_dir_from_angles(ti, rot, rl);
        sb_dir_from_angles(to, dp + rot, rv);
        int kx = sb_source_eval(s, l, v, x), ky = sb_source_eval(s, rl, rv, y), kz = sb_source_eval(s, rv, rl, z);
        known += kx != 0;
        differ += kx != ky || kx != kz || memcmp(x, y, sizeof x) != 0 || memcmp(x, z, sizeof x) != 0;
    }
    CHECKF(differ == 0 && known > 200, "%zu of 400 pairs differ when turned or swapped (%zu known)", differ, known);
    printf("  400 pairs, %zu known: the same bits turned about the normal and swapped\n", known);
    sb_source_destroy(s);
}
