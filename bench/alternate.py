#!/usr/bin/env python3
"""CPU seconds of commands timed in alternation (issue 36):

    bench/alternate.py ROUNDS 'CMD0' 'CMD1' ...

Every round runs each command once (order reversed every other round, so
neither side always runs first), each its own process started by
posix_spawn, stdout and stderr to /dev/null, and takes its user + system
CPU from wait4's rusage (the child alone: no shell, no timing process
forked beside it).  Prints, per command, the median (quartiles, Python's
statistics.quantiles; min-max) of its CPU seconds, and for every pair the per-round ratio CMDi / CMDj
the same way.  CPU, not wall: on a shared machine wall times carry the
load, and a per-round ratio cancels most of what the load does to both.
Example (a build before a change against one after, and the floor):

    bench/alternate.py 31 'build-old/sepbrdf_bench_floor -r 64 -J 8 -o /tmp/fl' \\
        'build-old/sepbrdf factor --param io -r 64 -J 8 -q -o /tmp/a' \\
        'build/sepbrdf factor --param io -r 64 -J 8 -q -o /tmp/b'
"""
import os
import shlex
import statistics
import sys


def run(argv):
    null = [(os.POSIX_SPAWN_OPEN, fd, os.devnull, os.O_WRONLY, 0) for fd in (1, 2)]
    pid = os.posix_spawnp(argv[0], argv, os.environ, file_actions=null)
    _, status, ru = os.wait4(pid, 0)
    if status != 0:
        print("bench/alternate.py: %s exited with status %d" % (" ".join(argv), status), file=sys.stderr)
    return ru.ru_utime + ru.ru_stime


def summary(v):
    v = sorted(v)
    q = statistics.quantiles(v, n=4) if len(v) >= 2 else [v[0]] * 3
    return "%.4f (%.4f-%.4f; %.4f-%.4f)" % (q[1], q[0], q[2], v[0], v[-1])


def main():
    if len(sys.argv) < 3 or not sys.argv[1].isdigit():
        sys.exit("usage: bench/alternate.py ROUNDS 'CMD0' ['CMD1' ...]")
    rounds, cmds = int(sys.argv[1]), [shlex.split(c) for c in sys.argv[2:]]
    cpu = [[] for _ in cmds]
    for r in range(rounds):
        order = range(len(cmds)) if r % 2 == 0 else reversed(range(len(cmds)))
        for i in order:
            cpu[i].append(run(cmds[i]))
    print("# %d rounds in alternation; CPU s median (quartiles; min-max); load %s"
          % (rounds, " ".join(open("/proc/loadavg").read().split()[0:3])))
    for i, c in enumerate(cmds):
        print("cmd%d %s  %s" % (i, summary(cpu[i]), " ".join(c)))
        for j in range(i):
            print("  cmd%d/cmd%d per round %s" % (i, j, summary([a / b for a, b in zip(cpu[i], cpu[j])])))


if __name__ == "__main__":
    main()
