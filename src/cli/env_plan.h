/* The environment the CLI runs in (env_plan.c): what OpenBLAS and the C
 * library read at process start, before main, so it is decided here and
 * passed to an exec, by the launcher (launch/launch.c) or by the CLI itself
 * when started directly (blas_env.c). */
#ifndef SB_CLI_ENV_PLAN_H
#define SB_CLI_ENV_PLAN_H

#include <stddef.h>

/* Entries of an environment the plan can hold (the rest are dropped). */
#define SB_ENV_MAX 1024

/* The value the CLI gives GLIBC_TUNABLES when the user did not set it. */
extern const char sb_env_malloc_tunables[];

/* out (SB_ENV_MAX entries, NULL-terminated) receives envp with what the
 * CLI wants added (pointers into envp and static strings).  Returns 1 when
 * that differs from envp, 0 when envp is already what the CLI wants. */
int sb_env_plan(char **envp, char **out);

/* Takes GLIBC_TUNABLES out of the environment again when it is the CLI's
 * own (first thing in main), so that the programs the CLI starts do not
 * inherit it (blas_env.c). */
void sb_cli_malloc_env_restore(void);

#endif
