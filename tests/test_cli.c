#include <math.h>
#include <stdio.h>
/* CLI: the real binary, its exit codes, files and messages. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"

static char out[65536];

static int run(const char *fmt, const char *arg) {
    char cmd[8192];
    char tail[4096];
    snprintf(tail, sizeof tail, fmt, arg);
    snprintf(cmd, sizeof cmd, "%s %s", SB_CLI, tail);
    return sb_run(cmd, out, sizeof out);
}

/* The number after "key": (array: after "key": [) in the JSON file at
 * path, its first occurrence; NAN where there is none. */
static double json_number_after(const char *path, const char *key, int array) {
    FILE *fp = fopen(path, "r");
    if (!fp) return NAN;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    buf[n] = 0;
    fclose(fp);
    char pat[128];
    snprintf(pat, sizeof pat, array ? "\"%s\": [" : "\"%s\": ", key);
    const char *p = strstr(buf, pat);
    return p ? atof(p + strlen(pat) + strspn(p + strlen(pat), " \n")) : NAN;
}

static double json_first_number(const char *path, const char *key) { return json_number_after(path, key, 0); }

/* The first number of the array at key in the JSON file at path. */
static double json_array_first(const char *path, const char *key) { return json_number_after(path, key, 1); }

/* 0 when the file at path holds a line matching the basic regex re. */
static int file_matches(const char *path, const char *re) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "grep -q '%s' %s", re, path);
    return sb_run(cmd, NULL, 0);
}

static int dir_is_empty_or_missing(const char *dir) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "test ! -e %s || test -z \"$(ls -A %s)\"", dir, dir);
    return sb_run(cmd, NULL, 0) == 0;
}

SB_TEST(default_job) {
    const char *dir = sb_tmpdir("cli");
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "cd %s && %s factor", dir, SB_CLI);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char path[1024];
    for (int j = 0; j < 4; j++) {
        snprintf(path, sizeof path, "%s/sepbrdf-out/g_%02d.exr", dir, j);
        CHECKF(sb_file_exists(path), "missing %s", path);
        snprintf(path, sizeof path, "%s/sepbrdf-out/h_%02d.exr", dir, j);
        CHECKF(sb_file_exists(path), "missing %s", path);
    }
    snprintf(path, sizeof path, "%s/sepbrdf-out/g_04.exr", dir);
    CHECK(!sb_file_exists(path));
    snprintf(path, sizeof path, "%s/sepbrdf-out/sepbrdf.glsl", dir);
    CHECK(sb_file_exists(path));
    snprintf(path, sizeof path, "%s/sepbrdf-out/report.json", dir);
    CHECK(sb_file_exists(path));
    CHECK(strstr(out, "rel_rms") != NULL);
}

SB_TEST(lambert_exact) {
    const char *dir = sb_tmpdir("cli");
    int rc = run("factor lambert:albedo=0.8 --res 16 --terms 1 -q -o %s", dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char path[1024];
    snprintf(path, sizeof path, "%s/report.json", dir);
    double e = json_first_number(path, "rel_rms");
    CHECKF(e >= 0 && e < 1e-12, "rel_rms %g", e);
    CHECK(out[0] == 0); /* -q prints nothing */
}

SB_TEST(bad_res) {
    const char *dir = sb_tmpdir("cli");
    char sub[2048];
    snprintf(sub, sizeof sub, "%s/o", dir);
    CHECK(run("factor --res 0 -o %s", sub) == 1);
    CHECK(strstr(out, "--res") != NULL);
    CHECK(dir_is_empty_or_missing(sub));
}

SB_TEST(bad_terms) {
    const char *dir = sb_tmpdir("cli");
    char sub[2048];
    snprintf(sub, sizeof sub, "%s/o", dir);
    CHECK(run("factor --terms -3 --out %s", sub) == 1);
    CHECK(strstr(out, "--terms") != NULL);
    CHECK(dir_is_empty_or_missing(sub));
    CHECK(run("factor --terms 300 --res 4 --out %s", sub) == 1);
    CHECK(strstr(out, "--terms") != NULL);
    CHECK(dir_is_empty_or_missing(sub));
}

SB_TEST(unknown_model) {
    const char *dir = sb_tmpdir("cli");
    char sub[2048];
    snprintf(sub, sizeof sub, "%s/o", dir);
    CHECK(run("factor nosuchmodel -o %s", sub) == 1);
    CHECK(strstr(out, "nosuchmodel") != NULL);
    CHECK(dir_is_empty_or_missing(sub));
    CHECK(run("factor lambert:albedo=2 -o %s", sub) == 1);
    CHECK(strstr(out, "albedo") != NULL);
    CHECK(run("factor microfacet:roughness=abc -o %s", sub) == 1);
    CHECK(strstr(out, "roughness") != NULL);
    CHECK(dir_is_empty_or_missing(sub));
}

SB_TEST(bad_option) {
    CHECK(run("factor --bogus%s", "") == 1);
    CHECK(strstr(out, "--bogus") != NULL);
    CHECK(run("nosuchcommand%s", "") == 1);
    CHECK(run("--help%s", "") == 0);
    CHECK(run("factor --help%s", "") == 0);
    CHECK(strstr(out, "--res") != NULL);
    CHECK(run("--version%s", "") == 0);
}

SB_TEST(list) {
    CHECK(run("list%s", "") == 0);
    CHECK(strstr(out, "lambert") && strstr(out, "microfacet") && strstr(out, "gold"));
}

/* A rerun with fewer terms into the same folder leaves no stale terms. */
SB_TEST(rerun_removes_stale_terms) {
    const char *dir = sb_tmpdir("cli");
    CHECK(run("factor lambert --param io --res 8 -J 5 -q -o %s", dir) == 0);
    char path[4200];
    snprintf(path, sizeof path, "%s/g_04.exr", dir);
    CHECK(sb_file_exists(path));
    CHECK(run("factor lambert --param io --res 8 -J 2 -q -o %s", dir) == 0);
    for (int j = 2; j < 5; j++) {
        snprintf(path, sizeof path, "%s/g_%02d.exr", dir, j);
        CHECKF(!sb_file_exists(path), "stale %s", path);
        snprintf(path, sizeof path, "%s/h_%02d.exr", dir, j);
        CHECKF(!sb_file_exists(path), "stale %s", path);
    }
    snprintf(path, sizeof path, "%s/h_01.exr", dir);
    CHECK(sb_file_exists(path));
}

/* --warp adaptive: the tables travel in the EXR headers' param spec (a
 * render from the folder reads them back), report.json and the snippet
 * hold them; an unknown warp is a usage error naming the option; io
 * takes none and the run warns. */
SB_TEST(warp_adaptive_round_trip) {
    const char *made = sb_tmpdir("cliwarp");
    char dir[1024], sub[1100], path[1200];
    snprintf(dir, sizeof dir, "%s", made);
    int rc = run("factor cook-torrance:roughness=0.1 --param iso --res 16 -J 2 --warp adaptive -q -o %s", dir);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/report.json", dir);
    CHECK(file_matches(path, "\"kind\": \"table\"") == 0);
    CHECK(file_matches(path, "\"param_spec\": \"iso:th=32,td=30,pd=8,warp_h=") == 0);
    snprintf(path, sizeof path, "%s/sepbrdf.glsl", dir);
    CHECK(file_matches(path, "const float sb_warp_h_x\\[65\\]") == 0);
    snprintf(sub, sizeof sub, "%s/render", dir);
    char args[2400];
    snprintf(args, sizeof args, "render %s -J 2 -q -o %s", dir, sub);
    rc = run("%s", args);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/render.json", sub);
    CHECK(sb_file_exists(path));
    CHECK(run("factor --warp bogus%s", "") == 1);
    CHECK(strstr(out, "--warp 'bogus' unknown") != NULL);
    /* a layout without warps says so */
    snprintf(args, sizeof args, "factor lambert --param io --res 8 -J 1 --warp merl -o %s", sub);
    CHECK(run("%s", args) == 0);
    CHECK(strstr(out, "io has no axis that takes a warp") != NULL);
}

/* --param takes a whole layout as report.json writes it (param_spec):
 * the same shape again, and its res checked against -r. */
SB_TEST(param_spec_round_trip) {
    const char *dir = sb_tmpdir("cli");
    char sub[2048], rep[2100];
    snprintf(sub, sizeof sub, "%s/o", dir);
    snprintf(rep, sizeof rep, "%s/report.json", sub);
    CHECK(run("factor blinn-phong -r 8 -J 2 --param iso:th=12,td=10,pd=6 -q -o %s", sub) == 0);
    CHECK(file_matches(rep, "\"param_spec\": \"iso:th=12,td=10,pd=6\"") == 0);
    CHECK(json_first_number(rep, "rows") == 12);
    CHECK(json_first_number(rep, "cols") == 60);
    CHECK(run("factor blinn-phong -r 8 -J 2 --param hd:res=6 -q -o %s", sub) != 0); /* res=6 against -r 8 */
    CHECK(strstr(out, "res=6") != NULL && strstr(out, "-r") != NULL);
    CHECK(run("factor blinn-phong -J 2 --param hd:res=6 -q -o %s", sub) == 0); /* res from the spec */
    CHECK(file_matches(rep, "\"param_spec\": \"hd:res=6\"") == 0);
    CHECK(run("factor blinn-phong -r 8 --param iso:th=x -o %s", sub) == 1);
    CHECK(strstr(out, "--param") != NULL && strstr(out, "not a number") != NULL);
    CHECK(run("factor blinn-phong -r 8 --param iso:res=8,warp_h=0.1/0.5 --warp merl -q -o %s", sub) != 0);
    CHECK(strstr(out, "--warp") != NULL);
}

/* `sepbrdf` is a launcher that executes sepbrdf-main next to it (or in
 * libexec/sepbrdf when installed: install_test.cmake); alone, it says what
 * is missing and exits 127 (also where a copy of it is named sepbrdf-main),
 * and it passes the arguments through as given. */
SB_TEST(launcher_alone_and_arguments) {
    const char *dir = sb_tmpdir("launch");
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "cp %s %s/sepbrdf", SB_CLI, dir);
    CHECK(system(cmd) == 0);
    snprintf(cmd, sizeof cmd, "%s/sepbrdf --version", dir);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 127, "rc %d: %s", rc, out);
    CHECKF(strstr(out, "sepbrdf-main") && strstr(out, "broken installation"), "%s", out);
    /* a copy of the launcher under the CLI's name does not run itself forever */
    snprintf(cmd, sizeof cmd, "cp %s %s/sepbrdf-main && timeout 10 %s/sepbrdf-main --version", SB_CLI, dir, dir);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 127 && strstr(out, "is this launcher"), "rc %d: %s", rc, out);
    snprintf(cmd, sizeof cmd, "%s factor lambert --res 4 --terms 1 -q -o '%s/with space'", SB_CLI, dir);
    rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0, "rc %d: %s", rc, out);
    char path[4300];
    snprintf(path, sizeof path, "%s/with space/report.json", dir);
    FILE *fp = fopen(path, "r");
    CHECKF(fp != NULL, "%s missing", path);
    if (fp) fclose(fp);
}

/* The CLI proper starts lean (CMakeLists.txt, SEPBRDF_LEAN_CLI_START;
 * issue 36 item 3): the loader maps neither libpng nor libgcc_s for
 * sepbrdf-main (their archives are linked in), and it is a PIE (ELF type
 * DYN, 3) unless SEPBRDF_CLI_NO_PIE asked for a position-dependent one
 * (EXEC, 2: OpenBLAS's kernel tables need no relocation at start).  LD_TRACE_LOADED_OBJECTS makes the loader list what
 * it maps and exit before any of the program runs. */
SB_TEST(main_linked_for_a_short_start) {
    if (!SB_CLI_LEAN_LINK && !SB_CLI_LEAN_PNG) SKIP("the CLI was linked without SEPBRDF_LEAN_CLI_START");
    char path[4096], cmd[8192];
    snprintf(path, sizeof path, "%s", SB_CLI);
    char *slash = strrchr(path, '/');
    CHECK(slash != NULL);
    if (!slash) return;
    snprintf(slash + 1, sizeof path - (size_t)(slash + 1 - path), "sepbrdf-main");
    unsigned char h[18] = {0};
    FILE *fp = fopen(path, "rb");
    CHECKF(fp != NULL, "%s missing", path);
    if (!fp) return;
    size_t n = fread(h, 1, sizeof h, fp);
    fclose(fp);
    CHECK(n == sizeof h && memcmp(h, "\177ELF", 4) == 0 && h[5] == 1); /* little-endian ELF */
    /* EXEC (2) only where asked for (SEPBRDF_CLI_NO_PIE); else PIE, DYN (3) */
    int want = SB_CLI_NO_PIE ? 2 : 3;
    CHECKF(h[16] == want && h[17] == 0, "%s: ELF type %d, not %d", path, h[16] | h[17] << 8, want);
    snprintf(cmd, sizeof cmd, "LD_TRACE_LOADED_OBJECTS=1 %s", path);
    int rc = sb_run(cmd, out, sizeof out);
    CHECKF(rc == 0 && strstr(out, "libc.so"), "rc %d: %s", rc, out);
    if (SB_CLI_LEAN_LINK) CHECKF(!strstr(out, "libgcc_s"), "%s", out);
    if (SB_CLI_LEAN_PNG) CHECKF(!strstr(out, "libpng"), "%s", out);
}

/* H5 (docs/measured.md): `factor --max-error 0.001` keeps J = 4 of a
 * 32-term fit, the same 4 terms as the default run (nested, fit_chain.c):
 * report.json's fit.converged and the warning are those of the terms
 * written, the same in both runs (the 32-term fit's last stage once set
 * it, and a dropped taps' round the default run's).  Both ran under
 * auto's early stop (fit.early_stop), whose cap is a stated rule: no
 * warning either way. */
SB_TEST(max_error_reports_the_terms_written) {
    const char *dir = sb_tmpdir("cli");
    char cmd[8192], path[2][1024], warned[2];
    const char *args[2] = {"", "--max-error 0.001 "};
    int conv[2] = {-1, -1};
    for (int i = 0; i < 2; i++) {
        snprintf(path[i], sizeof path[i], "%s/run%d/report.json", dir, i);
        snprintf(cmd, sizeof cmd, "%s factor %s-o %s/run%d", SB_CLI, args[i], dir, i);
        int rc = sb_run(cmd, out, sizeof out);
        CHECKF(rc == 0, "rc %d: %s", rc, out);
        warned[i] = strstr(out, "did not converge") != NULL;
        CHECKF(json_first_number(path[i], "terms") == 4, "%s: %.400s", args[i], out);
        char *rep = sb_read_file(path[i], NULL);
        const char *fit = rep ? strstr(rep, "\"fit\": {") : NULL, *c = fit ? strstr(fit, "\"converged\": ") : NULL;
        CHECKF(c != NULL, "%s: no fit.converged", path[i]);
        conv[i] = c && strncmp(c + 13, "true", 4) == 0;
        /* auto's early stop: a stage at its cap is its stated rule, no warning */
        const char *e = fit ? strstr(fit, "\"early_stop\": ") : NULL;
        CHECKF(e != NULL, "%s: no fit.early_stop", path[i]);
        int early = e && strncmp(e + 14, "true", 4) == 0;
        CHECKF(early, "%s: the default auto run is stopped early", args[i]);
        free(rep);
        CHECKF(!warned[i], "%s: converged %d under the early stop, yet a warning: %.600s", args[i], conv[i], out);
    }
    CHECKF(conv[0] == conv[1], "the same 4 terms: converged %d (default), %d (--max-error 0.001)", conv[0], conv[1]);
}

/* --unweighted with --method nmf: the non-negative fit weighs by solid
 * angle always (docs/positive.md), so the option is not applied, and
 * that is said (on main: silently, report.json "weighted": true). */
SB_TEST(unweighted_nmf_said) {
    const char *dir = sb_tmpdir("cli");
    int rc = run("factor lambert --param io -r 4 -J 1 --method nmf --unweighted -o %s", dir);
    CHECKF(rc == 0 && strstr(out, "--unweighted is not applied"), "rc %d: %s", rc, out);
}

/* factor's last line names every file it wrote: sampler.bin too, where
 * --method nmf gave a sampler (it named vndf.exr, report.json and the
 * snippets only), and not where the factors are signed. */
SB_TEST(last_line_names_the_sampler) {
    const char *dir = sb_tmpdir("cli_sampler_line");
    int rc = run("factor lambert --param io -r 4 -J 1 --method nmf -o %s/n", dir);
    CHECKF(rc == 0 && strstr(out, "wrote 1 texture pair, sampler.bin, report.json and sepbrdf.glsl"), "rc %d: %s", rc,
           out);
    char path[4200];
    snprintf(path, sizeof path, "%s/n/sampler.bin", dir);
    CHECKF(access(path, F_OK) == 0, "%s missing", path);
    rc = run("factor lambert --param io -r 4 -J 1 -o %s/s", dir);
    CHECKF(rc == 0 && strstr(out, "wrote 1 texture pair, report.json and sepbrdf.glsl"), "rc %d: %s", rc, out);
}

/* --theta-max below 90 without a scene: the errors (headline, bands,
 * auto's ranking, report.json) are measured within the cap, where the
 * snippet is defined, with the explicit cap scene's pairs; the fit is the
 * same.  On main they were measured over the whole hemisphere pair, where
 * the snippet returns 0 beyond the cap: GGX 0.5 at 60 degrees read 0.648
 * here (0.756 on every layout under auto) at every J, and a warning named
 * the scene instead. */
SB_TEST(theta_max_measured_within_cap) {
    const char *dir = sb_tmpdir("cli");
    char path[1024];
    int rc = run("factor --param iso -r 16 -J 2 --theta-max 60 -o %s/a", dir);
    CHECKF(rc == 0 && !strstr(out, "warning:") && strstr(out, "errors measured within the cap"), "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/a/report.json", dir);
    double h = json_first_number(path, "headline"), se = json_first_number(path, "headline_se");
    CHECKF(h < 0.01 && se > 0, "within the cap: headline %g +- %g (on main 0.648)", h, se);
    CHECKF(file_matches(path, "\"domain\": \"cap\"") == 0, "%s: no estimate.domain \"cap\"", path);
    rc = run("factor --param iso -r 16 -J 2 --theta-max 60 --scene 'view=0..60;light=0..60' -o %s/b", dir);
    /* the cap's scene fits as the unweighted fit does: no replacement of one by the same (on main a warning,
     * "worse inside the scene ... (0.0913 % against 0.0913 %)") */
    CHECKF(rc == 0 && !strstr(out, "worse inside the scene"), "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/b/report.json", dir);
    /* the unweighted fit (run a's) measured on the explicit scene's pairs: a's headline within its errors */
    double hs = json_array_first(path, "unweighted_headline"), ses = json_first_number(path, "headline_se");
    CHECKF(fabs(h - hs) <= 4 * hypot(se, ses) + 1e-12, "cap %g +- %g, the explicit scene %g +- %g", h, se, hs, ses);
    /* with a scene the whole domain is the cap too (on main the whole hemisphere, where the snippet returns
     * 0: 0.644), as the unweighted fit beside is measured now (else its ratio to it, 706x, replaced the fit) */
    const char *wd = strstr(out, "over the whole domain ");
    double d = wd ? atof(wd + strlen("over the whole domain ")) : NAN;
    CHECKF(d < 0.01 && !strstr(out, "x the unweighted fit's error"), "the whole domain %g: %s", d, out);
    /* a layout named alone is judged on the cap too: Lambert on io is exact there */
    rc = run("factor lambert --param io -r 8 -J 1 --theta-max 60 -o %s/c", dir);
    CHECKF(rc == 0 && !strstr(out, "warning:"), "rc %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/c/report.json", dir);
    CHECKF(json_first_number(path, "headline") < 1e-6, "lambert io in the cap: %g",
           json_first_number(path, "headline"));
}

/* --method nmf: the last line names sampler.bin (it named the textures,
 * report.json and the snippet).  Its other half, a layout without a
 * sampler said so on stderr, went with rv's sampler: no built-in layout
 * is left without one (test_extend.c's nmf_without_sampler_said checks
 * the warning on a program's own layout). */
SB_TEST(nmf_names_sampler_bin) {
    const char *dir = sb_tmpdir("cli");
    int rc = run("factor lambert --param io -r 8 -J 1 --method nmf -o %s/b", dir);
    CHECKF(rc == 0 && strstr(out, "wrote 1 texture pair, sampler.bin, report.json and sepbrdf.glsl to "), "rc %d: %s",
           rc, out);
}

/* A black source under --method nmf: nmf_over_svd is 0/0, null in
 * report.json; the table on stdout says "-" there as it does for a band
 * it cannot name (twelfth outside pass: "-nan"). */
SB_TEST(black_source_table_has_no_nan) {
    const char *dir = sb_tmpdir("cli_black");
    int rc = run("factor lambert:albedo=0 --param io -r 4 -J 1 --method nmf -o %s/b", dir);
    CHECKF(rc == 0 && strstr(out, "nmf_over_svd") && !strstr(out, "nan"), "rc %d: %s", rc, out);
}

/* Every list option refuses an empty item, as render -J and --shader did
 * (twelfth outside pass: study --param 'io,' and --budget '4K,', bench
 * --sizes '16,', --methods 'full,' and --pareto --layouts 'io,' were
 * read as the list without it): exit 1, the option named, no folder. */
SB_TEST(lists_refuse_empty_items) {
    const char *dir = sb_tmpdir("cli_lists");
    static const char *const cases[][2] = {
        {"study --param io, -o %s/s1", "--param"},
        {"study --param ,io -o %s/s2", "--param"},
        {"study --param io,,hd -o %s/s3", "--param"},
        {"study --budget 4K, -o %s/s4", "--budget"},
        {"bench --sizes 16, -o %s/b1", "--sizes"},
        {"bench --methods full, -o %s/b2", "--methods"},
        {"bench --pareto --layouts io, -o %s/b3", "--layouts"},
        {"bench --pareto --res 16, -o %s/b4", "--res"},
        {"study -J 1, -o %s/s5", "--terms"},
        {"factor --shader glsl, -o %s/f1", "--shader"},
        {"factor --channels R, -o %s/f2", "--channels"},
        {"factor --channels ,G -o %s/f3", "--channels"},
        {"batch lambert --channels R,,B -o %s/f4", "--channels"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int rc = run(cases[i][0], dir);
        CHECKF(rc == 1 && strstr(out, cases[i][1]), "%s: rc %d: %s", cases[i][0], rc, out);
    }
    char path[4200];
    const char *made[] = {"s1", "s2", "s3", "s4", "s5", "b1", "b2", "b3", "b4", "f1", "f2", "f3", "f4"};
    for (size_t i = 0; i < sizeof made / sizeof made[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, made[i]);
        CHECKF(access(path, F_OK) != 0, "%s was made", path);
    }
}
