import json, re, statistics as st, sys, os
"""Medians of the scaling runs (deploy/robots/SCALING.md): python3 deploy/robots/scaling_table.py DIR"""
D = sys.argv[1] if len(sys.argv) > 1 else 'results/scaling'
med = lambda xs: st.median(xs) if xs else float('nan')
rows = {}
for n in (19, 32, 64):
    r = {}
    for rnd in (1, 2, 3):
        f = f'{D}/dist_{n}_{rnd}.json'
        if not os.path.exists(f): continue
        d = json.load(open(f))
        if not d.get('survived'): print('NOT SURVIVED', f)
        for node in ('estimator', 'controller', 'contact'):
            for kind in ('compute_us', 'library_us', 'overhead_us'):
                for p in ('p50', 'p99'):
                    r.setdefault(f'{node}.{kind}.{p}', []).append(d[kind][node][p])
        for p in ('p50', 'p99'):
            r.setdefault(f'tick.{p}', []).append(d['tick_latency_us'][p])
        r.setdefault('rtf', []).append(d['realtime_factor'])
        s = json.load(open(f'{D}/logs_{n}_{rnd}/sim.summary.json'))
        for p in ('p50', 'p99'):
            r.setdefault(f'sim.compute_us.{p}', []).append(s['compute_us_run'][p])
            r.setdefault(f'sim.publish_us.{p}', []).append(s['publish_us'][p])
        t = open(f'{D}/loop_{n}_{rnd}.txt').read()
        m = re.search(r'in-process loop\s*:\s*([\d.]+)x real time \(([\d.]+) us per tick\)', t)
        if m:
            r.setdefault('loop.x', []).append(float(m.group(1)))
            r.setdefault('loop.us', []).append(float(m.group(2)))
    rows[n] = {k: med(v) for k, v in r.items()}
    rows[n]['_runs'] = len(r.get('rtf', []))
keys = sorted({k for n in rows for k in rows[n]})
print('| figure (median of runs) | 19 | 32 | 64 | 64/19 |')
print('|---|---|---|---|---|')
for k in keys:
    v = [rows[n].get(k, float('nan')) for n in (19, 32, 64)]
    ratio = v[2] / v[0] if v[0] else float('nan')
    print(f'| {k} | ' + ' | '.join(f'{x:.3g}' for x in v) + f' | {ratio:.2f} |')
