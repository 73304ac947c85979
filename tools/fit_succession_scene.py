#!/usr/bin/python3
"""Fit species parameters of the Sonoma biome to Fig. 15's shape on eco validate's own
succession scene (issue 28; docs/calibration.md "Fig. 15's shape on the validation scene").

eco calibrate's members are eco run pipelines, whose generated scene does not reproduce the
validation scene's early phase (docs/calibration.md); this driver runs NLopt's Subplex
(Debian python3-nlopt) over `eco validate --quick --only succession` runs of that scene at
a smaller plot instead, one replicate per scene seed, and writes every evaluation to a CSV.

  fit_succession_scene.py --eco build/apps/eco --out out/fit-fig15 [--max-evaluations 30]

Objective (chi2-like, each term (residual / sd)^2, means over the replicates):
  * Laurel's share of the plants at year 25: 0.05 +- 0.03 (scarce early);
  * Laurel's share over the last 25 years: 0.40 +- 0.07 (comes to dominate);
  * Laurel's count at 150 / its count at 50 at least 0.8 (one-sided, sd 0.1: it holds while
    the others subside), and its count at 150 / at 25 at least 1.0 (one-sided, sd 0.15).
Parameters (unit cube inside NLopt; --params, default the first fit's four): California
Laurel's sun optimum c (and optionally its sun range r), its max_age_years (log scale), its
max_height_m, and Toyon's alpha; --range NAME=LOW:HIGH:START changes one's range and start.
Everything else is the base biome (--base-biome).
"""
import argparse, csv, math, os, re, shutil, subprocess, sys
import nlopt

AVAILABLE = {  # name: (species, key, low, high, log, start)
    "laurel_sun_c": ("California Laurel", "sun_c", 2.0, 6.0, False, 4.0),
    "laurel_sun_r": ("California Laurel", "sun_r", 3.0, 12.0, False, 8.0),
    "laurel_max_age": ("California Laurel", "max_age_years", 150.0, 600.0, True, 400.0),
    "laurel_max_height": ("California Laurel", "max_height_m", 10.0, 30.0, False, 20.0),
    "toyon_alpha": ("Toyon", "alpha", 0.2, 0.7, False, 0.3),
}
PARAMS = []  # (name, species, key, low, high, log, start), set from --params

def to_unit(p, v):
    _, _, _, lo, hi, lg, _ = p
    return (math.log(v / lo) / math.log(hi / lo)) if lg else (v - lo) / (hi - lo)

def from_unit(p, u):
    _, _, _, lo, hi, lg, _ = p
    u = min(1.0, max(0.0, u))
    return lo * (hi / lo) ** u if lg else lo + u * (hi - lo)

def write_biome(base, out, values):
    lines = open(base).read().split("\n")
    for p, v in zip(PARAMS, values):
        _, sp, key, *_ = p
        cur, done = None, False
        for i, l in enumerate(lines):
            m = re.match(r'name = "(.*)"', l)
            if m:
                cur = m.group(1)
            if cur != sp:
                continue
            if key in ("sun_c", "sun_r") and l.startswith("sun ="):
                lines[i] = re.sub(key[-1] + r" = [0-9.]+", key[-1] + " = %.4f" % v, l); done = True; break
            if key == "max_age_years" and l.startswith("max_age_years"):
                lines[i] = "max_age_years = %d" % int(round(v)); done = True; break
            if key in ("max_height_m", "alpha") and re.match(key + r"\s*=", l):
                lines[i] = "%s = %.6f" % (key, v); done = True; break
        if not done:
            sys.exit("no %s.%s in %s" % (sp, key, base))
    open(out, "w").write("\n".join(lines))

def run_one(a, biome, cfg, out):
    cmd = ["nice", "-n", "10", a.eco, "validate", "--quick", "--configs", cfg, "--only", "succession",
           "--replicates", "1", "--biome", biome, "--model", "roulette_age_exponent=%s" % a.exponent,
           "--threads", "1", "--out", out]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rep = open(os.path.join(out, "report.md")).read()
    rows = {}
    for m in re.finditer(r"^\| ([A-Za-z -]+) \|((?: [0-9]+ \|){7})$", rep, re.M):
        rows[m.group(1)] = [int(x) for x in m.group(2).replace("|", " ").split()]
    tot = [sum(r[k] for r in rows.values()) for k in range(7)]
    L = rows["California Laurel"]
    m = re.search(r"California Laurel: ([0-9.]+) % of the plants at year 25, ([0-9.]+) % over the last 25 years", rep)
    return {"share25": L[1] / tot[1], "share_final": float(m.group(2)) / 100, "L25": L[1], "L50": L[2],
            "L150": L[6], "rows": rows}

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eco", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--base-biome", default="configs/calibrated/laurel-150-converged-biome.toml")
    ap.add_argument("--exponent", default="1.1225")
    ap.add_argument("--plot-size", type=float, default=60.0)
    ap.add_argument("--seeds", default="101,202", help="the scene seeds of the replicates")
    ap.add_argument("--max-evaluations", type=int, default=30)
    ap.add_argument("--tolerance", type=float, default=0.04)
    ap.add_argument("--initial-step", type=float, default=0.15)
    ap.add_argument("--params", default="laurel_sun_c,laurel_max_age,laurel_max_height,toyon_alpha",
                    help="parameters to fit, of: " + ", ".join(AVAILABLE))
    ap.add_argument("--range", action="append", default=[], metavar="NAME=LOW:HIGH:START",
                    help="another range and start for a parameter (repeatable)")
    a = ap.parse_args()
    for name in a.params.split(","):
        if name not in AVAILABLE:
            sys.exit("unknown parameter %r (one of %s)" % (name, ", ".join(AVAILABLE)))
        PARAMS.append((name,) + AVAILABLE[name])
    for r in a.range:
        name, spec = r.split("=", 1)
        lo, hi, st = (float(x) for x in spec.split(":"))
        k = [p[0] for p in PARAMS].index(name)
        PARAMS[k] = PARAMS[k][:3] + (lo, hi, PARAMS[k][5], st)
    os.makedirs(a.out, exist_ok=True)
    cfgs = []
    for s in a.seeds.split(","):
        d = os.path.join(a.out, "cfg-seed%s" % s)
        os.makedirs(d, exist_ok=True)
        shutil.copy("configs/validation/succession.toml", d)
        sc = open("configs/validation/scene_conifer_forest.toml").read()
        sc = re.sub(r"(\[quick\]\nplot_size_m = )[0-9.]+(\nyears = 150\nseed = )[0-9]+",
                    r"\g<1>%s\g<2>%s" % (a.plot_size, s), sc)
        open(os.path.join(d, "scene_conifer_forest.toml"), "w").write(sc)
        cfgs.append(d)
    hist = open(os.path.join(a.out, "history.csv"), "w", newline="")
    w = csv.writer(hist)
    w.writerow(["evaluation"] + [p[0] for p in PARAMS] + ["share25", "share_final", "hold_150_50", "gain_150_25", "chi2"])
    state = {"n": 0, "best": (float("inf"), None)}

    def objective(u, grad):
        state["n"] += 1
        n = state["n"]
        vals = [from_unit(p, x) for p, x in zip(PARAMS, u)]
        biome = os.path.join(a.out, "biome-%03d.toml" % n)
        write_biome(a.base_biome, biome, vals)
        res = [run_one(a, biome, c, os.path.join(a.out, "eval-%03d-r%d" % (n, k))) for k, c in enumerate(cfgs)]
        mean = lambda k: sum(r[k] for r in res) / len(res)
        s25, sfin = mean("share25"), mean("share_final")
        hold = sum(r["L150"] for r in res) / max(1, sum(r["L50"] for r in res))
        gain = sum(r["L150"] for r in res) / max(1, sum(r["L25"] for r in res))
        chi2 = ((s25 - 0.05) / 0.03) ** 2 + ((sfin - 0.40) / 0.07) ** 2 \
            + (max(0.0, 0.8 - hold) / 0.1) ** 2 + (max(0.0, 1.0 - gain) / 0.15) ** 2
        w.writerow([n] + ["%.5g" % v for v in vals] + ["%.4f" % s25, "%.4f" % sfin, "%.3f" % hold, "%.3f" % gain, "%.4f" % chi2])
        hist.flush()
        print("eval %d: %s -> share25 %.3f final %.3f hold %.2f gain %.2f chi2 %.3f" %
              (n, " ".join("%.4g" % v for v in vals), s25, sfin, hold, gain, chi2), flush=True)
        if chi2 < state["best"][0]:
            state["best"] = (chi2, vals, n)
            shutil.copy(biome, os.path.join(a.out, "best-biome.toml"))
        return chi2

    opt = nlopt.opt(nlopt.LN_SBPLX, len(PARAMS))
    opt.set_lower_bounds([0.0] * len(PARAMS))
    opt.set_upper_bounds([1.0] * len(PARAMS))
    opt.set_min_objective(objective)
    opt.set_maxeval(a.max_evaluations)
    opt.set_xtol_abs(a.tolerance)
    opt.set_initial_step(a.initial_step)
    x0 = [to_unit(p, p[6]) for p in PARAMS]
    try:
        opt.optimize(x0)
        why = {nlopt.XTOL_REACHED: "converged (xtol)", nlopt.MAXEVAL_REACHED: "max_evaluations"}.get(opt.last_optimize_result(), str(opt.last_optimize_result()))
    except nlopt.RoundoffLimited:
        why = "roundoff"
    chi2, vals, n = state["best"]
    print("best: evaluation %d, chi2 %.3f, %s; stopped: %s" % (n, chi2, dict(zip([p[0] for p in PARAMS], vals)), why))

if __name__ == "__main__":
    main()
