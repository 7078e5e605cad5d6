/* CLI: `sepbrdf batch` manifests read as CSV is read (issue 34): quoted
 * cells with commas, quotes and line breaks; a row with more cells than the
 * header is an error naming its row; nothing to do (an empty manifest, a
 * header alone, a folder without material files, a glob matching nothing)
 * is an error; a FIFO as manifest is refused at once. */
#include <stdlib.h>
#include <string.h>

#include "batch_util.h"
#include "harness.h"

static char out[65536];

/* Run `batch FILE -o m` in a fresh folder holding FILE with `text`. */
static int manifest_run(const char *tag, const char *file, const char *text) {
    const char *dir = sb_tmpdir(tag);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s/%s", dir, file);
    FILE *fp = fopen(cmd, "w");
    if (!fp) return -1;
    fputs(text, fp);
    fclose(fp);
    snprintf(cmd, sizeof cmd, "cd %s && %s batch %s -r 8 -J 1 -o m -q", dir, SB_CLI, file);
    return sb_run(cmd, out, sizeof out);
}

/* A comma inside a cell unquoted makes more cells than the header: an
 * error naming the file and row, not a material with a cut spec. */
SB_TEST(manifest_extra_cells) {
    int rc = manifest_run("batch_extra", "x.csv", "source\nlambert\nmicrofacet:base=silver,roughness=0.3\n");
    CHECKF(rc == 1, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "x.csv:3:") && strstr(out, "more cells"), "%s", out);
    rc = manifest_run("batch_extra2", "y.csv", "source,terms\nlambert,1,,\n");
    CHECKF(rc == 1 && strstr(out, "y.csv:2:"), "rc %d: %s", rc, out);
}

/* Quoted cells: commas, doubled quotes and line breaks inside; the rows
 * after a multi-line cell keep their line numbers. */
SB_TEST(manifest_quoted) {
    int rc = manifest_run("batch_quoted", "q.csv",
                          "source,terms\r\n\"microfacet:base=silver,roughness=0.3\",1\r\n\"lambert\",\"1\"\r\n");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = manifest_run("batch_quoted2", "q.csv", "source,form\n\"lambert\",\"f\nx\"\nlambert,bad\n");
    CHECKF(rc == 1 && strstr(out, "q.csv:2:") && strstr(out, "column 'form'"), "rc %d: %s", rc, out);
    rc = manifest_run("batch_quoted3", "q.csv", "source\n\"lambert\n");
    CHECKF(rc == 1 && strstr(out, "q.csv:2:") && strstr(out, "never closed"), "rc %d: %s", rc, out);
}

/* Manifest columns: `theta_max` (the Python package's spelling) is
 * --theta-max, and a column naming no option is an error at the header
 * (on main: theta_max "not an option of factor" at the first row that set
 * it, and a column `term` whose cells are empty ran every row without a
 * word, exit 0).  Seventh outside pass. */
SB_TEST(manifest_column_names) {
    int rc = manifest_run("batch_col1", "u.csv", "source,theta_max\nlambert,60\n");
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    rc = manifest_run("batch_col2", "t.csv", "source,term\nlambert,\nlambert,\n");
    CHECKF(rc == 1 && strstr(out, "t.csv:1: column 'term': not an option of factor"), "rc %d: %s", rc, out);
}

/* The quoted row factors the whole spec: silver at roughness 0.3. */
SB_TEST(manifest_quoted_spec_whole) {
    const char *dir = sb_tmpdir("batch_whole");
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd %s && printf 'source\\n\"microfacet:base=silver,roughness=0.3\"\\n' > q.csv && "
             "%s batch q.csv -r 8 -J 1 -o m -q",
             dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char *json = slurp(dir, "m/microfacet_base_silver_roughness_0.3", "report.json", NULL);
    char spec[256] = "";
    CHECK(json && report_value(json, "source_spec", spec, sizeof spec));
    CHECKF(strcmp(spec, "microfacet:base=silver,roughness=0.3") == 0, "source_spec %s", spec);
    free(json);
}

/* Nothing to do is an error: an empty manifest, a header alone, a folder
 * without material files, a glob matching nothing; a FIFO or device as
 * manifest is refused at once (no wait for a writer). */
SB_TEST(nothing_to_do_is_an_error) {
    static const char *const texts[][2] = {
        {"", "no 'source' column"}, {"source,terms\n", "no material rows"}, {"source\n\n\n", "no material rows"}};
    for (int i = 0; i < 3; i++) {
        int rc = manifest_run("batch_empty", "e.csv", texts[i][0]);
        CHECKF(rc == 1 && strstr(out, "e.csv") && strstr(out, texts[i][1]), "case %d: rc %d: %s", i, rc, out);
    }
    const char *dir = sb_tmpdir("batch_none");
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s && mkdir empty && touch empty/notes.txt && mkfifo f.csv", dir);
    CHECK(sb_run(cmd, out, sizeof out) == 0);
    static const char *const inputs[][2] = {{"empty", "'empty': no material file"},
                                            {"'empty/*.binary'", "matches no file"},
                                            {"f.csv", "f.csv: not a regular file"}};
    for (int i = 0; i < 3; i++) {
        snprintf(cmd, sizeof cmd, "cd %s && timeout 20 %s batch %s -o o", dir, SB_CLI, inputs[i][0]);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 2 && strstr(out, inputs[i][1]), "%s: rc %d: %s", inputs[i][0], rc, out);
    }
    snprintf(cmd, sizeof cmd, "cd %s && ls o 2>/dev/null | wc -l", dir);
    sb_run(cmd, out, sizeof out);
    CHECKF(atoi(out) == 0, "%s", out);
}

/* A flag's cell: weighted 0 fits unweighted (a layout named alone is
 * otherwise weighted, as auto fits it), weighted 1 overrides the command
 * line's --unweighted, and summary.csv says which each folder holds; a
 * flag's cell other than 1 or 0 is an error naming it. */
SB_TEST(manifest_weighted_cell) {
    const char *dir = sb_tmpdir("batch_w0");
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd %s && printf 'source,param,weighted\\nlambert,io,0\\n' > w.csv && %s batch w.csv -r 8 -J 1 -o m -q",
             dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char *json = slurp(dir, "m/lambert_io", "report.json", NULL), *csv = slurp(dir, "m", "summary.csv", NULL);
    CHECKF(json && strstr(json, "\n  \"weighted\": false,"), "%.300s", json ? json : "no report");
    CHECKF(csv && strstr(csv, "param,form,weighted,J,") && strstr(csv, "lambert_io,lambert,io:res=8,"), "%s",
           csv ? csv : "no summary");
    CHECKF(csv && strstr(strchr(csv, '\n'), ",0,1,"), "%s", csv ? csv : ""); /* weighted 0, J 1 */
    free(json), free(csv);
    dir = sb_tmpdir("batch_w1");
    snprintf(cmd, sizeof cmd,
             "cd %s && printf 'source,param,weighted\\nlambert,io,1\\n' > w.csv && "
             "%s batch w.csv -r 8 -J 1 --unweighted -o m -q",
             dir, SB_CLI);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    json = slurp(dir, "m/lambert_io", "report.json", NULL);
    CHECKF(json && strstr(json, "\n  \"weighted\": true,"), "%.300s", json ? json : "no report");
    free(json);
    rc = manifest_run("batch_wbad", "w.csv", "source,weighted\nlambert,yes\n");
    CHECKF(rc == 1 && strstr(out, "w.csv:2:") && strstr(out, "'yes' for a flag, need 1 or 0"), "rc %d: %s", rc, out);
}

/* A folder written before summary.csv had its weighted column (batch.txt
 * with one field fewer and no third line of sums) is reused, its fields in
 * their columns and the weighted cell empty. */
SB_TEST(folder_before_weighted_column) {
    const char *dir = sb_tmpdir("batch_old");
    char cmd[8192];
    snprintf(
        cmd, sizeof cmd,
        "cd %s && %s batch lambert -r 8 -J 1 -o m -q && "
        "awk -F'\\t' -v OFS='\\t' 'NR == 2 { $3 = \"\"; sub(/\\t\\t/, \"\\t\") } NR <= 2' m/lambert/batch.txt > b && "
        "mv b m/lambert/batch.txt && %s batch lambert -r 8 -J 1 -o m",
        dir, SB_CLI, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "1 reused"), "rc %d: %s", rc, out);
    char *csv = slurp(dir, "m", "summary.csv", NULL);
    const char *row = csv ? strchr(csv, '\n') : NULL;
    CHECKF(row && (strstr(row, ",f,,1,") || strstr(row, ",cos,,1,")), "%s", csv ? csv : "no summary");
    free(csv);
}

/* --out naming a file: said as every writing command says it, exit 2,
 * the file untouched. */
SB_TEST(out_is_a_file) {
    const char *dir = sb_tmpdir("batch_outfile");
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cd %s && printf 'keep' > f && %s batch lambert -r 8 -J 1 -o f", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 2 && strstr(out, "--out f: exists and is not a folder"), "rc %d: %s", rc, out);
    char *f = slurp(dir, "f", NULL, NULL);
    CHECKF(f && strcmp(f, "keep") == 0, "%s", f ? f : "gone");
    free(f);
}
