/* sepbrdf benchmark engine, shared by the `sepbrdf_bench` executable and
 * the `sepbrdf bench` subcommand.
 *
 * For every size N = R^2 of the io grid: sample the source once, take the
 * Eckart-Young baseline from LAPACK dgesdd (the full method's own errors
 * when it is listed, else the singular values of each channel), then for
 * every method and number of terms J run the factor step in a forked child
 * (so peak memory is per run): plan, execute, write the EXR textures when
 * the library has them.  Reports per
 * stage wall times, the relative error ||M - M_J||_F / ||M||_F, its excess
 * over the optimum, and peak memory; a table on stdout, CSV and a PNG plot
 * (gnuplot, when installed) in the output folder. */
#ifndef SEPBRDF_BENCH_H
#define SEPBRDF_BENCH_H

/* argv[0] is ignored; options as `--help` prints.  `prog` names the
 * command in messages.  Returns a process exit status (0, 1 usage, 2 I/O,
 * 3 numerical failure). */
int sb_bench_main(int argc, char **argv, const char *prog);

/* Called with the path of results.csv's temporary before it is created
 * (on = 1) and once it is renamed or removed (on = 0); NULL (the default,
 * sepbrdf_bench): nothing.  `sepbrdf bench` registers it with the CLI's
 * signal cleanup (cli_guard), so that SIGINT, SIGTERM or SIGHUP leaves
 * no results.csv.tmp-PID behind. */
extern void (*sb_bench_tmp_hook)(const char *path, int on);

/* The output folder DIR of option OPT (--out, --matrices), created with
 * its parents as every writing command creates its -o folder; 0, or 2
 * with "PROG: OPT DIR: why" on
 * stderr (exists and is not a folder, cannot create: errno's text). */
int sb_bench_out_dir(const char *prog, const char *opt, const char *dir);

#endif
