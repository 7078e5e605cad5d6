/* The CLI's environment (env_plan.c) when the CLI is started directly,
 * not through the launcher (launch/launch.c), e.g. from the build tree or
 * as libexec/sepbrdf/sepbrdf-main.  A function in .preinit_array runs
 * before the constructors of the shared libraries (but before the C library
 * has set up `environ`, so setenv there is lost): when the environment
 * lacks what the CLI wants, it executes the program again with it.  That
 * second start costs about 10 ms on the 2-core VM (the libraries are mapped
 * and relocated twice), which is why `sepbrdf` is a launcher. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "env_plan.h"

static void env_for_blas(int argc, char **argv, char **envp) {
    static char *env[SB_ENV_MAX];
    (void)argc;
    if (!envp || !sb_env_plan(envp, env)) return;
    execve("/proc/self/exe", argv, env); /* returns only on failure: run as is */
}

void sb_cli_malloc_env_restore(void) {
    const char *v = getenv("GLIBC_TUNABLES");
    if (v && strcmp(v, sb_env_malloc_tunables) == 0) unsetenv("GLIBC_TUNABLES");
}

__attribute__((used, section(".preinit_array"))) static void (*const sb_preinit_blas)(int, char **,
                                                                                      char **) = env_for_blas;
