#!/usr/bin/env python3
# usage: scripts/eval_tables.py EVAL.json [EVAL.json ...]   (docs/evaluation.md)
# The Markdown tables of docs/evaluation.md from one or more `freeform eval` reports (e.g.
# the chunks of one run made with --only): per-shape errors and fitting residuals, the
# averages over shapes per (test, basis) -- the same means as `freeform eval`'s own -- and
# the precompute times. A shape present in several reports (as a result or a failure) is
# taken from the last.
import json, math, sys

shapes, failures, opts = {}, {}, None
for path in sys.argv[1:]:
    rep = json.load(open(path))
    if opts is not None and rep['options']['protocol'] != opts['protocol']:
        sys.exit(f"{path}: another protocol than the first report's; not merging")
    opts = rep['options']
    # A later report's results and failures replace an earlier one's for the same shape.
    for name in [s['name'] for s in rep['shapes']] + [f['name'] for f in rep['failures']]:
        shapes.pop(name, None)
        failures.pop(name, None)
    for s in rep['shapes']:
        shapes[s['name']] = s
    for f in rep['failures']:
        failures[f['name']] = f['reason']
order = sorted(shapes, key=lambda n: (shapes[n]['fem_tets'], n))
tests = ['fix_side', 'pull_farthest', 'pull_ends']
runs = {(n, r['test'], r['boundaries']): r for n in order for r in shapes[n]['runs']}

def g(v):
    return '-' if v is None else f"{v:.2e}"

print(f"## Per shape ({len(order)} shapes, sorted by FEM size)\n")
print("| shape | faces | tets / FE nodes | test | free MSE | free max | aware MSE | aware max | free fit MSE | aware fit MSE |")
print("|---|---|---|---|---|---|---|---|---|---|")
for n in order:
    s = shapes[n]
    for i, t in enumerate(tests):
        f, a = runs.get((n, t, 'free')), runs.get((n, t, 'aware'))
        head = (f"| {n} | {s['faces']:,} | {s['fem_tets']:,} / {s['fem_nodes']:,} " if i == 0
                else "| | | ")
        print(head + f"| {t.replace('_', ' ')} | {g(f and f['normalized_mse'])} | "
              f"{g(f and f['max_error'])} | {g(a and a['normalized_mse'])} | "
              f"{g(a and a['max_error'])} | {g(f and f['fit_mse'])} | {g(a and a['fit_mse'])} |")
    for msg in s['failures']:
        print(f"| {n} | | | FAILED: {msg} | | | | | | |")
for n, why in failures.items():
    print(f"| {n} | | | FAILED: {why} | | | | | | |")

print("\n## Averages over shapes\n")
print("| basis | quantity | " + " | ".join(f"{t.replace('_', ' ')} MSE | max" for t in tests) + " |")
print("|---|---|" + "---|---|" * len(tests))
for b in ['free', 'aware']:
    for label, key, sq in [('error', 'normalized_mse', 'max_error'),
                           ('fit residual', 'fit_mse', 'fit_max')]:
        cells = []
        for t in tests:
            rs = [runs[(n, t, b)] for n in order if (n, t, b) in runs]
            cells += [g(sum(r[key] for r in rs) / len(rs)) if rs else '-',
                      g(sum(r[sq] for r in rs) / len(rs)) if rs else '-']
        print(f"| {b} | {label} | " + " | ".join(cells) + " |")
    cells = []
    for t in tests:
        rs = [runs[(n, t, b)] for n in order if (n, t, b) in runs]
        cells += ['', g(sum(r['max_error'] ** 2 for r in rs) / len(rs)) if rs else '-']
    print(f"| {b} | error, mean of max^2 | " + " | ".join(cells) + " |")

nonconv = sum(r['reduced_nonconverged_steps'] for r in runs.values())
steps = opts['protocol']['steps'] * len(runs)
print(f"\nReduced steps not converged: {nonconv} of {steps}.")

print("\n## Precompute (free basis, one per shape), s wall\n")
print("| shape | basis | basis + model setup (mean of the 3 tests) | reduced step, ms (mean) | FEM step, ms (mean) |")
print("|---|---|---|---|---|")
basis = []
for n in order:
    rs = [runs[(n, t, 'free')] for t in tests if (n, t, 'free') in runs]
    if not rs:
        continue
    basis.append(rs[0]['basis_s'])
    pre = sum(r['precompute_s'] for r in rs) / len(rs)
    step = sum(r['reduced_step_ms_mean'] for r in rs) / len(rs)
    fem = sum(r['fem_step_ms_mean'] for r in rs) / len(rs)
    print(f"| {n} | {rs[0]['basis_s']:.2f} | {pre:.2f} | {step:.1f} | {fem:.0f} |")
if basis:
    m = sum(basis) / len(basis)
    sd = math.sqrt(sum((x - m) ** 2 for x in basis) / len(basis))
    print(f"\nFree basis over {len(basis)} shapes: {m:.2f} s +- {sd:.2f} s (population std).")
