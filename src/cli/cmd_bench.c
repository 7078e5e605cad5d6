/* sepbrdf bench: the benchmark engine of bench/bench.c as a subcommand
 * (same options as the sepbrdf_bench executable; `--quick` for a short
 * run), and with --pareto the whole job's CPU time against its headline
 * error over layouts, methods, R and J (bench/pareto.c). */
#include <stdio.h>
#include <string.h>

#include "bench.h"
#include "cli.h"
#include "pareto.h"

/* results.csv's temporary, removed by the signal cleanup. */
static void bench_guard(const char *path, int on) {
    if (on)
        cli_guard(path);
    else
        cli_unguard(path);
}

int cmd_bench(int argc, char **argv) {
    sb_bench_tmp_hook = bench_guard;
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--pareto") == 0) return sb_bench_pareto_main(argc, argv, "sepbrdf bench");
    int rc = sb_bench_main(argc, argv, "sepbrdf bench");
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0)
            printf("\nsepbrdf bench --pareto [OPTIONS]: CPU seconds of the whole factor job against its\n"
                   "headline error over layouts, methods, R and J, the Pareto front marked\n"
                   "(pareto.csv, pareto.png); `sepbrdf bench --pareto --help` lists its options.\n");
    return rc;
}
