#!/usr/bin/env python3
"""Where the automatic RoFi rule's distance to the oracle comes from (docs/algorithms/rofi.md,
"Stopping", "Why the target is out of reach").

Reads the two TSVs `rofi_autostop --full --curves CURVES --trace TRACE` writes and prints, per
mesh and over the family:
  auto      the automatic rule (its stop and its maximum p, both read off the trace): the
            trace at the stop's iteration;
  stop*     the best iteration of the automatic parameters (k <= 80): a perfect stop;
  oracle    the best of the grid (sigma_s, lambda_I, r = 2 sigma_c, p);
  universal the one grid setting with the lowest worst ratio to the oracle over all meshes;
  transfer  the oracle setting of the other seed of the same mesh and noise (the best
            parameters for this surface and noise level, chosen on another noise draw);
and the split auto/oracle = (auto/stop*) x (stop*/oracle): the part a better stop could win
and the part only other parameters could. Last, the pairs of different surfaces whose noise
estimates (sigma_n, theta) agree within the estimate's own seed-to-seed spread: a rule that
takes (sigma_s, lambda_I, disk) from the estimate gives both the same ones, so the lowest over
the grid of the larger of the two ratios (each at its own best p: any stop) bounds such a rule
from below on that pair.
With a third TSV, `rofi_autostop --full --no-oracle --trace-sigma 0.5,0.7,0.9,1.2 --trace
SIGMAS`: each sigma_s stopped by W (the rule's maximum, and the trace's length), one of them picked per mesh with the
truth (the best a choice among them could do) and without it (the largest residual at the
stop: the run that removed the most before its residual stopped being white).
Usage: rofi_oracle_analysis.py CURVES TRACE [SIGMAS]
"""

import collections
import math
import sys


def read_tsv(path):
    with open(path, encoding="utf-8") as f:
        header = f.readline().rstrip("\n").split("\t")
        for line in f:
            fields = line.rstrip("\n").split("\t")
            if len(fields) == len(header):  # a run still writing ends in a partial line
                yield dict(zip(header, fields))


def median(v):
    v = sorted(v)
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def stop_k(t, maximum):
    """RofiStop::kWhiteResidual on a trace {k: (msae, created, W, threshold, ...)}: the
    iteration after which the run stops (W_k at or below its threshold, or the maximum)."""
    for k in sorted(t):
        if k >= maximum or (t[k][2] > 0 and t[k][2] <= t[k][3]):
            return k
    return max(t)


def other_seed(m):
    """The same surface and noise with the other seed ("... s1" <-> "... s2"), or None."""
    if m.endswith(" s1"):
        return m[:-1] + "2"
    if m.endswith(" s2"):
        return m[:-1] + "1"
    return None


def sigma_choice(sigmas_path, oracle, rule, rule_maximum):
    runs = collections.defaultdict(lambda: collections.defaultdict(dict))
    for row in read_tsv(sigmas_path):
        runs[row["mesh"]][float(row["sigma_s"])][int(row["k"])] = (
            float(row["msae"]), int(row["created"]), float(row["whiteness"]),
            float(row["threshold"]), float(row["delta_le"]))
    print()
    print("sigma_s chosen per mesh among %s, each stopped by W:" % sorted(
        {s for m in runs for s in runs[m]}))
    longest = max(max(t) for m in runs for t in runs[m].values())
    for maximum in (rule_maximum, longest):
        for pick in ("truth", "largest residual"):
            ratios, worse = [], 0
            for m, by_sigma in runs.items():
                if m not in oracle:
                    continue
                stopped = {s: t[stop_k(t, maximum)] for s, t in by_sigma.items()}
                if pick == "truth":
                    best = min(stopped.values(), key=lambda q: q[0])
                else:
                    best = max(stopped.values(), key=lambda q: q[4])
                ratios.append(best[0] / oracle[m])
                worse += best[0] > rule[m] * (1 + 1e-4)
            print("  maximum %2d, picked by %-16s n=%2d median %.3f worst %.3f  <= 1.05 on %2d"
                  "  worse than the rule on %d" % (maximum, pick, len(ratios), median(ratios),
                                                   max(ratios),
                                                   sum(1 for x in ratios if x <= 1.05), worse))


def main(curves_path, trace_path, sigmas_path=None):
    # grid[mesh][(sigma_s, lambda_i, r, k)] = (msae, created)
    grid = collections.defaultdict(dict)
    for row in read_tsv(curves_path):
        if row["config"] != "grid":
            continue
        key = (float(row["sigma_s"]), float(row["lambda_i"]), float(row["r"]), int(row["k"]))
        grid[row["mesh"]][key] = (float(row["msae"]), int(row["created"]))
    # trace[mesh][k] = (msae, created, W, threshold); the noise estimate and the rule's maximum
    # p are the same on every row of a mesh
    trace = collections.defaultdict(dict)
    estimate = {}
    rule_maximum = None
    for row in read_tsv(trace_path):
        if "rule_iterations" not in row:
            sys.exit("%s: a trace of an older rofi_autostop (no noise estimate, no maximum p): "
                     "write it again" % trace_path)
        trace[row["mesh"]][int(row["k"])] = (float(row["msae"]), int(row["created"]),
                                             float(row["whiteness"]), float(row["threshold"]))
        estimate[row["mesh"]] = (float(row["noise_sigma_le"]), float(row["normal_angle_deg"]))
        rule_maximum = int(row["rule_iterations"])
    meshes = [m for m in trace if m in grid]
    oracle = {m: min(grid[m].items(), key=lambda kv: kv[1][0]) for m in meshes}

    # The universal setting: the grid key (over the keys every mesh has) whose worst ratio to
    # each mesh's oracle is lowest.
    common = set.intersection(*(set(grid[m]) for m in meshes))
    universal = min(common, key=lambda s: max(grid[m][s][0] / oracle[m][1][0] for m in meshes))

    print("%-26s %4s %7s %3s | %4s %7s | %7s %3s %-24s | %6s %6s %6s | %6s %6s" % (
        "mesh", "p", "auto", "cr", "k*", "stop*", "oracle", "cr", "(s_s, l_I, r, p)", "a/or", "a/st*",
        "st*/or", "univ", "transf"))
    ratios = collections.defaultdict(list)
    more_flips = []
    for m in meshes:
        k = stop_k(trace[m], rule_maximum)
        a = trace[m][k][0]
        kbest = min(trace[m], key=lambda kk: trace[m][kk][0])
        s = trace[m][kbest][0]
        (ss, li, r, p), (o, ocr) = oracle[m]
        u = grid[m][universal][0] / o
        om = other_seed(m)
        t = float("nan")
        if om in oracle and oracle[om][0] in grid[m]:
            t = grid[m][oracle[om][0]][0] / o
        ratios["auto"].append(a / o)
        ratios["stop"].append(a / s)
        ratios["param"].append(s / o)
        ratios["univ"].append(u)
        if not math.isnan(t):
            ratios["transfer"].append(t)
        if trace[m][k][1] > ocr:
            more_flips.append(m)
        print("%-26s %4d %7.3f %3d | %4d %7.3f | %7.3f %3d %-24s | %6.3f %6.3f %6.3f | %6.3f %6.3f" % (
            m, k, a, trace[m][k][1], kbest, s, o, ocr, "(%.2g, %.2g, %.0f, %d)" % (ss, li, r, p), a / o, a / s,
            s / o, u, t))
    print()
    print("universal setting (sigma_s, lambda_I, r/c_a, p) = (%.2g, %.2g, %.0f, %d)" % universal)
    for name, label in (("auto", "auto / oracle"), ("stop", "auto / perfect stop"),
                        ("param", "perfect stop / oracle"), ("univ", "universal / oracle"),
                        ("transfer", "other seed's oracle / oracle")):
        v = ratios[name]
        if not v:  # "transfer" needs both seeds (--full)
            continue
        print("%-30s n=%2d median %.3f mean %.3f worst %.3f  <= 1.05 on %d" % (
            label, len(v), median(v), sum(v) / len(v), max(v), sum(1 for x in v if x <= 1.05)))
    print("auto creates more flips than the oracle on %d of %d: %s" % (
        len(more_flips), len(meshes), ", ".join(more_flips)))

    if sigmas_path:
        sigma_choice(sigmas_path, {m: oracle[m][1][0] for m in meshes},
                     {m: trace[m][stop_k(trace[m], rule_maximum)][0] for m in meshes},
                     rule_maximum)

    # Pairs of different surfaces with indistinguishable noise estimates.
    best_p = {m: {} for m in meshes}
    for m in meshes:
        for (ss, li, r, k), (v, _) in grid[m].items():
            key = (ss, li, r)
            best_p[m][key] = min(best_p[m].get(key, math.inf), v)
    seeds = [m for m in meshes if m.endswith(" s1") and other_seed(m) in estimate]
    if not seeds:
        return
    d_sigma = max(abs(estimate[m][0] - estimate[other_seed(m)][0]) for m in seeds)
    d_theta = max(abs(estimate[m][1] - estimate[other_seed(m)][1]) for m in seeds)
    bounds = []
    for i, a in enumerate(meshes):
        for b in meshes[i + 1:]:
            if a.split()[0] == b.split()[0]:
                continue
            if (abs(estimate[a][0] - estimate[b][0]) > d_sigma
                    or abs(estimate[a][1] - estimate[b][1]) > d_theta):
                continue
            keys = set(best_p[a]) & set(best_p[b])
            worst = lambda s: max(best_p[a][s] / oracle[a][1][0], best_p[b][s] / oracle[b][1][0])
            s = min(keys, key=worst)
            bounds.append((worst(s), a, b, s))
    bounds.sort(reverse=True)
    print()
    print("pairs of different surfaces with noise estimates within the seed-to-seed spread "
          "(sigma_n %.4f l_e, theta %.2f deg): %d; the bound is above 1.05 on %d" % (
              d_sigma, d_theta, len(bounds), sum(1 for x in bounds if x[0] > 1.05)))
    for bound, a, b, s in bounds[:5]:
        print("  %.3f  %-24s (%.3f, %5.2f)  %-24s (%.3f, %5.2f)  at (%.2g, %.2g, %.0f)" % (
            bound, a, estimate[a][0], estimate[a][1], b, estimate[b][0], estimate[b][1], *s))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit("usage: rofi_oracle_analysis.py CURVES TRACE [SIGMAS]")
    main(*sys.argv[1:])
