#!/usr/bin/env python3
"""What positivity costs on each layout (issue 38 item 1, round h38l):

    bench/positive_layouts.py BUILD OUT FILE... [--layouts auto,vndf,...] [-J 4]

For every FILE and layout (auto and each named one; default auto, vndf,
vh, hd, rv, io, io-area) runs `sepbrdf factor FILE [--param P] -J J
--method nmf` and the same without --method nmf (the SVD default there),
and prints one line each: the layout kept, the non-negative fit's headline
at J' = 1..J, the SVD's, the pooled errors[].nmf_over_svd, the worst
channel's at each J', the worst of all (* above 1.5), the non-negative
headline at J over auto's non-negative one (the same FILE) and over auto's
SVD (the SVD default), whether the fit keeps
the band bounds at J (theta_i > 80 within max(3 h, 1 %), > 89 within
max(10 h, 5 %), as sb_estimate_bands_bounded without its standard
errors), and each run's CPU seconds (one run: time with bench/alternate.py).
FILE `default`: the embedded default gold (no source argument).
"""
import json
import os
import sys


def run(argv):
    null = [(os.POSIX_SPAWN_OPEN, fd, os.devnull, os.O_WRONLY, 0) for fd in (1, 2)]
    pid = os.posix_spawnp(argv[0], argv, os.environ, file_actions=null)
    _, status, ru = os.wait4(pid, 0)
    return status, ru.ru_utime + ru.ru_stime


def bounded(e):
    h, b = e["headline"], e["band_rel"]
    return b["theta_i_80"] <= max(3 * h, 0.01) and b["theta_i_89"] <= max(10 * h, 0.05)


def main():
    args, layouts, terms = [], "auto,vndf,vh,hd,rv,io,io-area", "4"
    it = iter(sys.argv[1:])
    for a in it:
        if a == "--layouts":
            layouts = next(it)
        elif a == "-J":
            terms = next(it)
        else:
            args.append(a)
    if len(args) < 3:
        sys.exit(__doc__)
    exe, out, files = os.path.join(args[0], "sepbrdf"), args[1], args[2:]
    for f in files:
        tag = os.path.basename(f).rsplit(".", 1)[0]
        rows, ref = [], None  # auto's nmf and SVD headlines at J
        for p in layouts.split(","):
            par = [] if p == "auto" else ["--param", p]
            rep, cpu = {}, {}
            for m, extra in (("nmf", ["--method", "nmf"]), ("svd", [])):
                d = os.path.join(out, "%s.%s.%s" % (tag, p, m))
                st, cpu[m] = run([exe, "factor"] + ([] if f == "default" else [f]) + par + ["-J", terms, "-q", "-o", d] + extra)
                rep[m] = json.load(open(os.path.join(d, "report.json"))) if st == 0 else None
            if not rep["nmf"] or not rep["svd"]:
                rows.append("%-24s %-7s failed" % (tag, p))
                continue
            e, s = rep["nmf"]["errors"], rep["svd"]["errors"]
            pooled = [x["nmf_over_svd"] for x in e]
            chan = [max((x.get("nmf_over_svd_channel") or {"-": 0}).values()) for x in e]
            worst = max(pooled + chan)
            lay = rep["nmf"]["param"]
            lay = lay if isinstance(lay, str) else lay.get("name", "?")
            if p == "auto":
                ref = (e[-1]["headline"], s[-1]["headline"])
            rows.append((tag, p, lay, e, s, pooled, chan, worst, cpu))
        for r in rows:
            if isinstance(r, str):
                print(r)
                continue
            tag, p, lay, e, s, pooled, chan, worst, cpu = r
            print("%-24s %-7s %-7s nmf %s | svd %s | pooled %s | chan %s | worst %.2f%s | "
                  "/auto %s | bands %s | cpu %.2f %.2f" % (tag, p, lay, " ".join("%.4f" % x["headline"] for x in e),
                                     " ".join("%.4f" % x["headline"] for x in s), " ".join("%.2f" % v for v in pooled),
                                     " ".join("%.2f" % v for v in chan), worst, " *" if worst > 1.5 else "",
                                     "%.2f %.2f" % (e[-1]["headline"] / ref[0], e[-1]["headline"] / ref[1])
                                     if ref else "-",
                                     "ok" if bounded(e[-1]) else "broken", cpu["nmf"], cpu["svd"]))


if __name__ == "__main__":
    main()
