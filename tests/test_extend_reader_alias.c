/* A reader in the library that reuses another's reading (docs/architecture.md,
 * "Adding a kind"): the sepbrdf CSV under another name and magic, its
 * descriptor written as a file of src/source/ would be, with CSV's reading
 * (sb_gonio_read_csv_) and the shared table builder (sb_gonio_open_) of
 * src/source/gonio_impl.h.  Registered here through the public call (in the
 * library it would be one X(name) row in measured.c).  It must read exactly
 * what the CSV reader reads: the same rows, samples and values. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "sepbrdf/sepbrdf.h"
#include "source/gonio_impl.h"

#define ALIAS_MAGIC "# xcsv table"

static int sniff_xcsv(const unsigned char *head, size_t n) {
    size_t m = strlen(ALIAS_MAGIC);
    return n >= m && memcmp(head, ALIAS_MAGIC, m) == 0 ? 2 : 0;
}

static sb_result_t open_xcsv(sb_context_t *ctx, const char *path, const sb_measured_opts_t *o, sb_source_t **out,
                             sb_measured_info_t *info) {
    return sb_gonio_open_(ctx, path, sb_gonio_read_csv_, o, out, info);
}

static const sb_reader_t sb_reader_xcsv = {"xcsv", "sepbrdf CSV under another name", ".xcsv", sniff_xcsv, open_xcsv};

SB_TEST(csv_alias_reads_as_csv) {
    CHECK(sb_measured_register_reader(&sb_reader_xcsv) == SB_OK);
    char csv[4200], alias[4200];
    snprintf(csv, sizeof csv, "%s/data/example_gonio.csv", SB_SOURCE_DIR);
    snprintf(alias, sizeof alias, "%s/table.txt", sb_tmpdir("extend-alias"));
    size_t n = 0;
    char *text = sb_read_file(csv, &n);
    FILE *fp = text ? fopen(alias, "w") : NULL;
    CHECKF(fp != NULL, "cannot copy %s to %s", csv, alias);
    if (!fp) {
        free(text);
        return;
    }
    fprintf(fp, "%s\n%s", ALIAS_MAGIC, text); /* a comment line more: CSV skips it */
    fclose(fp);
    free(text);

    sb_measured_info_t ia, ic;
    sb_source_t *a = NULL, *c = NULL;
    CHECK(sb_measured_open(NULL, alias, NULL, &a, &ia) == SB_OK);
    CHECK(sb_measured_open(NULL, csv, NULL, &c, &ic) == SB_OK);
    if (!a || !c) goto done;
    CHECK(strcmp(ia.format, "xcsv") == 0 && strcmp(ic.format, "csv") == 0);
    CHECK(ia.rows == ic.rows && ia.samples == ic.samples && ia.channels == ic.channels && ia.samples > 0);
    CHECK(sb_source_flags(a) == sb_source_flags(c));
    CHECK(sb_source_sample_count(a) == sb_source_sample_count(c));
    for (size_t k = 0; k < sb_source_sample_count(c); k++) {
        double wa[3], va[3], fa[3], wc[3], vc[3], fc[3], ra[3], rc[3];
        int ka = sb_source_sample(a, k, wa, va, fa), kc = sb_source_sample(c, k, wc, vc, fc);
        CHECKF(ka == kc && memcmp(wa, wc, sizeof wa) == 0 && memcmp(va, vc, sizeof va) == 0 &&
                   memcmp(fa, fc, sizeof fa) == 0,
               "sample %zu differs", k);
        /* and the interpolated sources agree bit for bit at the pair */
        CHECKF(sb_source_eval(a, wc, vc, ra) == sb_source_eval(c, wc, vc, rc) && memcmp(ra, rc, sizeof ra) == 0,
               "eval at sample %zu differs", k);
        if (sb_test_failed_now()) break;
    }
done:
    sb_source_destroy(a);
    sb_source_destroy(c);
}
