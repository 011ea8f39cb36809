"""The stiff-minority scene of the study (scene `minority` of scripts/bench/study.py): the talk's
spinning neo-Hookean cube (0.1 m, rubber, 100 rad/s about z) on Gmsh meshes whose stable Verlet step
is set by a small share of the elements, while the rest of the body is soft and smooth:

  - band:      a thin layer of small elements through the cube (a Gmsh Box size field);
  - slivers:   the cube with a cylindrical hole, meshed by Gmsh's Delaunay without its optimization
               passes, so the flat tetrahedra a generator leaves stay (quality spread reported);
  - inclusion: a small stiff cube inside (its own Gmsh volume entity, E x 100 at the same Poisson's
               ratio: &potential volume_lambda(v), volume_mu(v)), about 1 % of the elements.

Per variant, with the machinery of solids.py (its decks, error measures and bisection): velocity
Verlet's largest stable step by bisection of dt = t_end / N; a Verlet reference at a twentieth of it;
Verlet sweeps at fractions of the stable step and energy stepping over h, each run ending exactly at
t_end, against the reference (largest node-position difference at t_end, max |E - E0|, the kinetic
energy history); per-element CFL estimates dt_e = (smallest altitude of e) / c_d(e), c_d =
sqrt((lambda + 2 mu) / rho), and the quality spread (radius ratio 3 r_in / R_circ, 1 for a regular
tetrahedron). Writes bench_data/minority_<mode>.json and .csv, figures/bench_minority.png and the page
section between <!-- minority:begin --> and <!-- minority:end --> of benchmarks.md.
"""
import csv
import json
import os
import re
import shutil
import subprocess

import numpy as np

from . import solids
from .common import splice_section

LAM, MU, RHO = 2.7e6, 3.0e5, 1100.0
STIFF = 100.0                 # the inclusion's moduli: x 100 (the same Poisson's ratio)
VARIANTS = ['band', 'slivers', 'inclusion']
TITLES = {'band': '(a) refinement band: a thin layer of small elements through the cube',
          'slivers': '(b) slivers: the cube with a hole, Delaunay without optimization',
          'inclusion': '(c) stiff inclusion: E x %g in a small cube inside' % STIFF}
SHORT = {'band': '(a) refinement band', 'slivers': '(b) slivers', 'inclusion': '(c) stiff inclusion'}

PARAMS = {
    'quick': dict(t_long=0.03, thermo=0.0005, ref_factor=16, vv_fractions=[0.9, 0.5, 0.25],
                  hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5], h_base=1e-3, es_timeout=240,
                  band=dict(size=0.0125, band_size=0.0025, half_width=0.0008, grade=0.004),
                  slivers=dict(size=0.0125, hole=0.02),
                  inclusion=dict(size=0.0125, side=0.009, corner=(0.01, 0.005, -0.02))),
    'full': dict(t_long=0.05, thermo=0.0005, ref_factor=32, vv_fractions=[0.9, 0.5, 0.25, 0.125],
                 hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5], h_base=1e-3, es_timeout=3600,
                 band=dict(size=0.01, band_size=0.002, half_width=0.0006, grade=0.003),
                 slivers=dict(size=0.01, hole=0.02),
                 inclusion=dict(size=0.01, side=0.0072, corner=(0.01, 0.005, -0.02))),
}

_BOX = 'Box(1) = {-0.05, -0.05, -0.05, 0.1, 0.1, 0.1};\n'


# ------------------------------------------------------------------------------------ meshes
def geo_text(variant, q, baseline=False):
    """The Gmsh script of one variant (OpenCASCADE kernel; one physical volume, body 1). BASELINE: the
    same shape without its minority (band: no size field; slivers: Gmsh's default optimization; the
    inclusion's mesh is the same, only its material differs)."""
    g = 'SetFactory("OpenCASCADE");\n' + _BOX
    if variant == 'band' and baseline:
        g += 'Physical Volume(1) = {1};\nMesh.MeshSizeMax = %r;\n' % q['size']
    elif variant == 'slivers' and baseline:
        g += ('Cylinder(2) = {0.0, 0.0, -0.06, 0, 0, 0.12, %r};\n'
              'BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }\n'
              'Physical Volume(1) = Volume{:};\nMesh.MeshSizeMax = %r;\n' % (q['hole'], q['size']))
    elif variant == 'band':
        g += ('Physical Volume(1) = {1};\n'
              'Field[1] = Box;\nField[1].VIn = %r; Field[1].VOut = %r;\n'
              'Field[1].XMin = %r; Field[1].XMax = %r;\n'
              'Field[1].YMin = -1; Field[1].YMax = 1; Field[1].ZMin = -1; Field[1].ZMax = 1;\n'
              'Field[1].Thickness = %r;\nBackground Field = 1;\n'
              'Mesh.MeshSizeExtendFromBoundary = 0; Mesh.MeshSizeFromPoints = 0; Mesh.MeshSizeFromCurvature = 0;\n'
              % (q['band_size'], q['size'], -q['half_width'], q['half_width'], q['grade']))
    elif variant == 'slivers':
        g += ('Cylinder(2) = {0.0, 0.0, -0.06, 0, 0, 0.12, %r};\n'
              'BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }\n'
              'Physical Volume(1) = Volume{:};\n'
              'Mesh.MeshSizeMax = %r;\nMesh.Optimize = 0;\nMesh.Algorithm3D = 1;\n' % (q['hole'], q['size']))
    else:
        c = q['corner']
        g += ('Box(2) = {%r, %r, %r, %r, %r, %r};\n'
              'BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }\n'
              'Physical Volume(1) = Volume{:};\n'
              'Mesh.MeshSizeMax = %r;\nMesh.MeshSizeMin = %r;\n'
              % (c[0], c[1], c[2], q['side'], q['side'], q['side'], q['size'], q['size']))
    return g


def gmsh_exe():
    exe = shutil.which('gmsh')
    if not exe:
        raise RuntimeError('minority: the gmsh command is not installed (pip install gmsh, or apt-get install gmsh)')
    return exe


def make_mesh(variant, q, work, baseline=False):
    """Writes <variant>.geo and meshes it with the gmsh command (MSH 2.2: physical and elementary tags
    on each element line). Returns the file name and the Gmsh version."""
    name = 'minority_%s%s' % (variant, '_baseline' if baseline else '')
    with open(os.path.join(work, name + '.geo'), 'w') as f:
        f.write(geo_text(variant, q, baseline))
    exe = gmsh_exe()
    r = subprocess.run([exe, '-3', '-format', 'msh22', '-save_all', '0', name + '.geo', '-o', name + '.msh'],
                       cwd=work, capture_output=True, text=True, timeout=600)
    if r.returncode != 0 or not os.path.exists(os.path.join(work, name + '.msh')):
        raise RuntimeError('minority: gmsh failed on %s.geo: %s' % (name, (r.stdout + r.stderr).strip()[-300:]))
    ver = subprocess.run([exe, '--version'], capture_output=True, text=True).stdout.strip() or \
        subprocess.run([exe, '--version'], capture_output=True, text=True).stderr.strip()
    return name + '.msh', ver


def read_msh22(path):
    """Nodes (by tag 1..N), tetrahedra (node tags), their physical and elementary (volume entity) tags."""
    text = open(path).read()
    nodes = text.split('$Nodes\n')[1].split('$EndNodes')[0].split('\n')
    n = int(nodes[0])
    x = np.zeros((n + 1, 3))
    for line in nodes[1:n + 1]:
        t = line.split()
        x[int(t[0])] = [float(v) for v in t[1:4]]
    els = text.split('$Elements\n')[1].split('$EndElements')[0].split('\n')
    tets, phys, elem = [], [], []
    for line in els[1:int(els[0]) + 1]:
        t = [int(v) for v in line.split()]
        if t[1] != 4:
            continue
        nt = t[2]
        phys.append(t[3])
        elem.append(t[4] if nt >= 2 else 0)
        tets.append(t[3 + nt:7 + nt])
    return x, np.array(tets), np.array(phys), np.array(elem)


def quality(x, tets):
    """Per element: signed volume (> 0: positively oriented), smallest altitude, radius ratio 3 r_in / R_circ."""
    p = x[tets]                                     # (ne, 4, 3)
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    det = np.einsum('ij,ij->i', a, np.cross(b, c))
    vol = det / 6.0
    faces = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    areas = np.stack([0.5 * np.linalg.norm(np.cross(p[:, j] - p[:, i], p[:, k] - p[:, i]), axis=1)
                      for i, j, k in faces], 1)
    alt = 3.0 * np.abs(vol) / areas.max(1)          # the smallest altitude: over the largest face
    r_in = 3.0 * np.abs(vol) / areas.sum(1)
    # circumradius: |a|^2 (b x c) + |b|^2 (c x a) + |c|^2 (a x b) over 2 det
    cc = (np.sum(a * a, 1)[:, None] * np.cross(b, c) + np.sum(b * b, 1)[:, None] * np.cross(c, a)
          + np.sum(c * c, 1)[:, None] * np.cross(a, b)) / (2.0 * det[:, None])
    r_circ = np.linalg.norm(cc, axis=1)
    return vol, alt, 3.0 * r_in / r_circ


def inclusion_volume(x, tets, elem, q):
    """The volume entity whose elements lie inside the inclusion's box (centroids)."""
    lo = np.array(q['corner'])
    hi = lo + q['side']
    cen = x[tets].mean(1)
    inside = np.all((cen > lo) & (cen < hi), 1)
    tags = sorted(set(elem[inside].tolist()))
    if len(tags) != 1 or np.any(inside != (elem == tags[0])):
        raise RuntimeError('minority: the inclusion is not one volume entity of the mesh (%s)' % tags)
    return tags[0]


def mesh_facts(variant, q, work, mesh, baseline=False):
    x, tets, phys, elem = read_msh22(os.path.join(work, mesh))
    vol, alt, rr = quality(x, tets)
    if np.any(vol <= 0):
        raise RuntimeError('minority: %s has %d inverted tetrahedra' % (mesh, int(np.sum(vol <= 0))))
    lam = np.full(len(tets), LAM)
    mu = np.full(len(tets), MU)
    facts = dict(nodes=int(len(np.unique(tets))), elements=int(len(tets)), volume=float(vol.sum()),
                 entities=sorted(set(elem.tolist())))
    material = "&potential style='neohookean', lambda=%r, mu=%r /" % (LAM, MU)
    minority = np.zeros(len(tets), bool)
    if variant == 'inclusion' and not baseline:
        v = inclusion_volume(x, tets, elem, q)
        minority = elem == v
        lam[minority] *= STIFF
        mu[minority] *= STIFF
        material = ("&potential style='neohookean', lambda=%r, mu=%r, volume_lambda(%d)=%r, volume_mu(%d)=%r /"
                    % (LAM, MU, v, STIFF * LAM, v, STIFF * MU))
        facts['inclusion_entity'] = int(v)
    cd = np.sqrt((lam + 2 * mu) / RHO)
    dte = alt / cd                                   # per-element CFL estimate
    if baseline:
        minority[:] = False
    elif variant == 'band':
        cen = x[tets].mean(1)
        minority = np.abs(cen[:, 0]) < q['half_width'] + 0.5 * q['band_size']
    elif variant == 'slivers':
        minority = rr < 0.1
    facts.update(
        quality=dict(min=float(rr.min()), median=float(np.median(rr)), max=float(rr.max()),
                     below_01=int(np.sum(rr < 0.1)), below_02=int(np.sum(rr < 0.2))),
        alt=dict(min=float(alt.min()), median=float(np.median(alt)), max=float(alt.max())),
        dte=dict(min=float(dte.min()), median=float(np.median(dte)), max=float(dte.max())),
        minority=int(minority.sum()), minority_volume=float(vol[minority].sum() / vol.sum()),
        # the softest element's estimate: the largest dt_e among elements of the default material
        dte_soft=float(dte[~minority].max()) if np.any(~minority) else float(dte.max()),
        dte_soft_median=float(np.median(dte[~minority])) if np.any(~minority) else float(np.median(dte)),
        dte_stiff=float(dte.min()),
        hist_rr=np.histogram(rr, bins=np.linspace(0, 1, 21))[0].tolist(),
        hist_dte=[float('%.4g' % v) for v in np.sort(dte)[:: max(1, len(dte) // 400)]])
    return facts, material


# ------------------------------------------------------------------------------------ runs
def _solid_p(P):
    return dict(t_long=P['t_long'], thermo=P['thermo'], dt_ref=None)


def run_variant(ctx, variant, P, work):
    q = P[variant]
    mesh, gver = make_mesh(variant, q, work)
    facts, material = mesh_facts(variant, q, work, mesh)
    print('    minority %-9s %s: %d nodes, %d tetrahedra; minority %d elements (%.2f %% of the volume); radius ratio '
          'min %.3g median %.3g; CFL estimates %.3g s (stiffest) to %.3g s (softest)'
          % (variant, mesh, facts['nodes'], facts['elements'], facts['minority'], 100 * facts['minority_volume'],
             facts['quality']['min'], facts['quality']['median'], facts['dte_stiff'], facts['dte_soft']), flush=True)
    res = dict(variant=variant, mesh=mesh, gmsh=gver, geo=geo_text(variant, q), facts=facts, material=material,
               params=dict(P, **{variant: q}))
    saved = solids.MATERIAL
    solids.MATERIAL = material
    try:
        p = dict(t_long=P['t_long'], thermo=P['thermo'], dt_ref=facts['dte_stiff'])
        bs = _bisect(ctx, variant, work, mesh, p, facts, P)
        res['bisect'] = bs
        stable = bs['stable']
        p['dt_ref'] = stable / P['ref_factor']
        ref, _ = solids.one_run(ctx, 'cube', work, mesh, 'verlet', p['dt_ref'], p)
        if ref['rc'] != 0:
            raise RuntimeError('minority %s: reference failed: %s' % (variant, ref['error']))
        xref = dict(x=ref.pop('x'), k_hist=ref.pop('k_hist'))
        res['reference'] = ref
        print('    minority %-9s stable Verlet dt %.3g s; reference dt %.3g s: cpu %.2f s, max|dE| %.3g J'
              % (variant, stable, ref['param'], ref['cpu'], ref['max_de']), flush=True)
        rows = []
        runs = [('verlet', float('%.3g' % (f * stable))) for f in P['vv_fractions']] + \
            [('stepping', h) for h in P['hs']]
        for method, v in runs:
            old = ctx.timeout
            if method == 'stepping':
                ctx.timeout = P['es_timeout']
            try:
                row, _ = solids.one_run(ctx, 'cube', work, mesh, method, v, p, ref=xref)
            finally:
                ctx.timeout = old
            row.pop('x', None)
            row.pop('k_hist', None)
            if row['rc'] == 124:
                row['error'] = 'over %d s' % P['es_timeout']
            rows.append(row)
            if row['rc'] == 0:
                print('    minority %-9s %-9s %-10.3g cpu %7.2f s  max|dE| %9.3g J  pos err %9.3g m%s'
                      % (variant, method, v, row['cpu'], row['max_de'], row['pos_err'],
                         '  %d events, mean interval %.3g s, %.1f %% reflections'
                         % (row['events'], row['mean_dt'], 100.0 * (row.get('refl') or 0) / row['events'])
                         if method == 'stepping' else ''), flush=True)
            else:
                print('    minority %-9s %-9s %-10.3g FAILED: %s' % (variant, method, v, row['error']), flush=True)
        res['rows'] = rows
        # the same shape without its minority: Verlet's stable step and energy stepping at one h
        if variant == 'inclusion':
            bmesh, bfacts = mesh, mesh_facts(variant, q, work, mesh, baseline=True)[0]
        else:
            bmesh = make_mesh(variant, q, work, baseline=True)[0]
            bfacts = mesh_facts(variant, q, work, bmesh, baseline=True)[0]
        solids.MATERIAL = "&potential style='neohookean', lambda=%r, mu=%r /" % (LAM, MU)
        bb = _bisect(ctx, variant, work, bmesh, dict(p, dt_ref=bfacts['dte_stiff']), bfacts, P)
        base = dict(mesh=bmesh, geo=geo_text(variant, q, True), facts=bfacts, bisect=bb)
        old = ctx.timeout
        ctx.timeout = P['es_timeout']
        try:
            row, _ = solids.one_run(ctx, 'cube', work, bmesh, 'stepping', P['h_base'], dict(p, dt_ref=bfacts['dte_stiff']))
        finally:
            ctx.timeout = old
        base['es'] = {k: v for k, v in row.items() if k not in ('x', 'k_hist')}
        res['es_base'] = next((r for r in rows if r['method'] == 'stepping' and r['param'] == P['h_base']), {})
        res['baseline'] = base
        print('    minority %-9s without the minority (%d tetrahedra): stable Verlet dt %.3g s (with: %.3g s); energy '
              'stepping at h = %g J: %s events (with: %s)' % (variant, bfacts['elements'], bb['stable'], bs['stable'],
                                                             P['h_base'], base['es'].get('events'),
                                                             res['es_base'].get('events')), flush=True)
    finally:
        solids.MATERIAL = saved
    for f in os.listdir(work):
        if f.endswith('.h5') or f.endswith('.final'):
            os.remove(os.path.join(work, f))
    return res


def _bisect(ctx, variant, work, mesh, p, facts, P):
    """Verlet's largest stable step on MESH (solids.bisect_dt), bracketed by the CFL estimates."""
    lo, hi = 0.5 * facts['dte_stiff'], min(4.0 * facts['dte_soft'], P['thermo'])   # thermo: at least dt/2
    for _ in range(4):
        try:
            bs = solids.bisect_dt(ctx, 'cube', work, mesh, p, lo, hi, P['t_long'])
            break
        except RuntimeError:
            lo *= 0.25
    else:
        raise RuntimeError('minority %s: no stable Verlet step found on %s down to %g s' % (variant, mesh, lo))
    bs['fail_why'] = solids.short_why(bs.get('fail_why', '-') or '-')
    return bs


def run(ctx):
    P = PARAMS[ctx.mode]
    work = os.path.join(ctx.work, 'minority')
    os.makedirs(work, exist_ok=True)
    out = dict(mode=ctx.mode, env=dict(ctx.env), variants={})
    for v in VARIANTS:
        try:
            out['variants'][v] = run_variant(ctx, v, P, work)
        except RuntimeError as err:
            print('    minority %s: FAILED: %s' % (v, err), flush=True)
            out['variants'][v] = dict(variant=v, failed=str(err))
    save(ctx, out)
    return out


# ------------------------------------------------------------------------------------ output
def save(ctx, res):
    base = os.path.join(ctx.data, 'minority_%s' % res['mode'])
    with open(base + '.json', 'w') as f:
        json.dump(res, f, indent=1)
    fields = ['variant', 'method', 'param', 'rc', 'cpu', 'cpu_base', 'wall', 'n', 'max_de', 'max_dl', 'pos_err',
              'ke_err', 'events', 'mean_dt', 'evals', 'refl', 'error']
    with open(base + '.csv', 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(fields)
        for v, r in res['variants'].items():
            if r.get('failed'):
                continue
            for row in [dict(r['reference'], method='reference')] + r['rows']:
                row = dict(row, variant=v)
                w.writerow(['' if row.get(k) is None else ('%.6g' % row[k] if isinstance(row[k], float) else row[k])
                            for k in fields])


def load(ctx):
    path = os.path.join(ctx.data, 'minority_%s.json' % ctx.mode)
    return json.load(open(path)) if os.path.exists(path) else None


def _ok(rows, method):
    return sorted([r for r in rows if r['method'] == method and r['rc'] == 0 and r.get('pos_err')],
                  key=lambda r: r['param'])


def figure(res, path):
    import matplotlib.ticker
    from terrace_tools.plotting import plt, save as save_figure
    vs = [v for v in VARIANTS if v in res['variants'] and not res['variants'][v].get('failed')]
    if not vs:
        return
    fig, axs = plt.subplots(1, len(vs), figsize=(5.0 * len(vs), 4.9), squeeze=False)
    for ax, v in zip(axs[0], vs):
        r = res['variants'][v]
        for m, col, mk, name in (('verlet', 'tab:blue', 'o', 'velocity Verlet (labels: dt [s])'),
                                 ('stepping', 'tab:red', 's', 'energy stepping (labels: h [J])')):
            pts = _ok(r['rows'], m)
            if not pts:
                continue
            ax.loglog([p['pos_err'] for p in pts], [p['cpu'] for p in pts], '-', color=col, marker=mk, label=name)
            for p in pts:
                lab = '%.2g' % p['param']
                if m == 'stepping' and p.get('events'):
                    lab += ' (%.0f %% refl.)' % (100.0 * (p.get('refl') or 0) / p['events'])
                ax.annotate(lab, (p['pos_err'], p['cpu']), textcoords='offset points', xytext=(4, 3), fontsize=7,
                            color=col)
        f = r['facts']
        ax.set_title('%s\n%d tetrahedra, %d in the minority; Verlet stable dt %.2g s'
                     % (SHORT[v], f['elements'], f['minority'], r['bisect']['stable']), fontsize=9)
        ax.set_xlabel('max node-position error at t = %g s [m]' % res['variants'][v]['params']['t_long'])
        ax.set_ylabel('CPU time [s] (run less a zero-length run)')
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(True, which='both', alpha=0.3)
    h, lab = axs[0][0].get_legend_handles_labels()
    fig.legend(h, lab, loc='lower center', ncol=2, fontsize=8)
    fig.suptitle("Stiff minority: the talk's spinning rubber cube (0.1 m, 100 rad/s) on Gmsh meshes with a minority "
                 "of small, flat or stiff elements", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.93))
    save_figure(fig, path, dpi=110, tight=False)


def _verdict(r):
    """Equal-error comparison on the position error: per h, the cheapest Verlet run with no larger error."""
    vv = _ok(r['rows'], 'verlet')
    out = []
    for e in _ok(r['rows'], 'stepping'):
        good = [q for q in vv if q['pos_err'] <= e['pos_err']]
        q = min(good, key=lambda q: q['cpu']) if good else None
        out.append((e, q))
    return out


def section(ctx, res):
    if not res:
        return []
    e = res['env']
    L = ['<!-- minority:begin -->', '## The stiff minority: meshes whose stable Verlet step a few elements set\n',
         '`%s` (commit %s%s), %s, load %s at the start; made by `scripts/bench/study/minority.py`.\n'
         % (re.sub(r' --work \S+', '', e.get('command', '?')), e.get('commit', '?'),
            ' + uncommitted changes' if e.get('dirty') else '', e.get('date', '?'), e.get('load', '?')),
         "The talk's spinning cube (0.1 m, rubber: lambda = %.3g Pa, mu = %.3g Pa, density %g kg/m^3, 100 rad/s "
         "about z, from its reference shape) on three Gmsh meshes (the `.geo` scripts are in "
         "`doc/bench_data/minority_%s.json`), where a minority of small, flat or stiff elements sets velocity "
         "Verlet's stable step while the rest of the body is soft and smooth. Per variant: Verlet's largest "
         "stable step (bisection of dt = t_end / N to 3 %%, failure as in the cube and balls section), a Verlet "
         "reference at 1/%d of it, Verlet at %s of the stable step and energy stepping at h = %s J, every run "
         "ending exactly at t_end; cost: CPU time less a zero-length run, as above. The CFL estimate of an "
         "element is dt_e = (its smallest altitude) / c_d, c_d = sqrt((lambda + 2 mu)/rho) its dilatational "
         "wave speed; the softest element is the default-material element of largest dt_e, the stiffest the "
         "element of smallest dt_e. Quality: the radius ratio 3 r_in / R_circ (1 for a regular tetrahedron).\n"
         % (LAM, MU, RHO, res['mode'], PARAMS[res['mode']]['ref_factor'],
            ', '.join('%g' % f for f in PARAMS[res['mode']]['vv_fractions']),
            ', '.join('%g' % h for h in PARAMS[res['mode']]['hs']))]
    L.append('| variant | mesh (Gmsh %s) | minority: elements (share of elements; of the volume) | radius ratio min / median / max '
             '(elements < 0.1) | CFL estimate: stiffest element [s] | softest element [s] | Verlet largest stable dt '
             '[s] | stable dt / stiffest estimate | fails at [s] |'
             % (next((r['gmsh'] for r in res['variants'].values() if r.get('gmsh')), '?')))
    L.append('|---' * 9 + '|')
    for v in VARIANTS:
        r = res['variants'].get(v)
        if not r:
            continue
        if r.get('failed'):
            L.append('| %s | failed: %s |%s' % (SHORT[v], r['failed'].replace('|', '\\|'), ' |' * 7))
            continue
        f, b = r['facts'], r['bisect']
        L.append('| %s | %d nodes, %d tetrahedra | %d (%.2g %%; %.2g %%) | %.3g / %.3g / %.3g (%d) | %.3g | %.3g | **%.3g** | '
                 '%.2g | %.3g: %s |' % (SHORT[v], f['nodes'], f['elements'], f['minority'],
                                       100.0 * f['minority'] / f['elements'], 100 * f['minority_volume'],
                                       f['quality']['min'], f['quality']['median'], f['quality']['max'],
                                       f['quality']['below_01'], f['dte_stiff'], f['dte_soft'], b['stable'],
                                       b['stable'] / f['dte_stiff'], b['fail'] or float('nan'), b.get('fail_why', '-')))
    L.append('')
    L.append('Minority: (a) the elements whose centroid lies in the refined layer, (b) those of radius ratio below '
             '0.1, (c) the inclusion\'s elements.\n')
    L.append('What the minority costs each method: the same shape without it ((a) the cube meshed at the base size, '
             'no size field; (b) the same geometry with Gmsh\'s default optimization; (c) the same mesh, one '
             'material): Verlet\'s largest stable step (bisection as above) and energy stepping at h = %g J over '
             'the same %g s.\n' % (PARAMS[res['mode']]['h_base'], PARAMS[res['mode']]['t_long']))
    L.append('| variant | without: mesh | without: radius ratio min | without: Verlet stable dt [s] | with: Verlet '
             'stable dt [s] | Verlet steps, with / without | without: energy stepping events (reflections), CPU [s] | '
             'with: events (reflections), CPU [s] | energy stepping events, with / without |')
    L.append('|---' * 9 + '|')
    for v in VARIANTS:
        r = res['variants'].get(v)
        if not r or r.get('failed') or not r.get('baseline'):
            continue
        b, eb, ew = r['baseline'], r['baseline']['es'], r.get('es_base') or {}

        def ev(x):
            return ('%d (%.1f %%), %.3g' % (x['events'], 100.0 * (x.get('refl') or 0) / x['events'], x['cpu'])
                    if x.get('rc') == 0 and x.get('events') else 'failed: %s' % x.get('error', '-'))
        L.append('| %s | %d tetrahedra | %.3g | %.3g | %.3g | **%.2g** | %s | %s | **%s** |' % (
            SHORT[v], b['facts']['elements'], b['facts']['quality']['min'], b['bisect']['stable'], r['bisect']['stable'],
            b['bisect']['stable'] / r['bisect']['stable'], ev(eb), ev(ew),
            '%.2g' % (ew['events'] / eb['events']) if ew.get('events') and eb.get('events') else '–'))
    L.append('')
    L.append('| variant | method | dt [s] or h [J] | CPU [s] | steps or events | events per Verlet step at the stable dt '
             '| reflections | max \\|E − E0\\| [J] | max position error [m] |')
    L.append('|---' * 9 + '|')
    for v in VARIANTS:
        r = res['variants'].get(v)
        if not r or r.get('failed'):
            continue
        nst = r['params']['t_long'] / r['bisect']['stable']
        for row in r['rows']:
            es = row['method'] == 'stepping'
            if row['rc'] != 0:
                L.append('| %s | %s | %.3g | failed: %s |%s' % (SHORT[v], 'energy stepping' if es else 'velocity Verlet',
                                                              row['param'], row['error'].replace('|', '\\|')[:80],
                                                              ' |' * 5))
                continue
            L.append('| %s | %s | %.3g | %.3g | %d | %s | %s | %.2g | %.3g |' % (
                SHORT[v], 'energy stepping' if es else 'velocity Verlet', row['param'], row['cpu'],
                row['events'] if es else row['n'], '%.2g' % (row['events'] / nst) if es else '–',
                ('%.1f %%' % (100.0 * (row.get('refl') or 0) / row['events'])) if es else '–',
                row['max_de'], row['pos_err']))
    L.append('')
    L.append('| variant | energy stepping h [J] | its position error [m], CPU [s] | cheapest Verlet run with no larger '
             'position error: dt [s], CPU [s] | CPU ratio energy stepping / Verlet | events / steps |')
    L.append('|---|---|---|---|---|---|')
    ratios = {}
    for v in VARIANTS:
        r = res['variants'].get(v)
        if not r or r.get('failed'):
            continue
        for es, q in _verdict(r):
            if q is None:
                L.append('| %s | %g | %.3g, %.3g | none as accurate | – | – |' % (SHORT[v], es['param'], es['pos_err'],
                                                                               es['cpu']))
                continue
            ratios.setdefault(v, []).append(es['cpu'] / q['cpu'])
            L.append('| %s | %g | %.3g, %.3g | %.3g, %.3g | **%.3g** | %d / %d = %.3g |'
                     % (SHORT[v], es['param'], es['pos_err'], es['cpu'], q['param'], q['cpu'], es['cpu'] / q['cpu'],
                        es['events'], q['n'], es['events'] / q['n']))
    L.append('')
    words = []
    for v in VARIANTS:
        if v not in ratios:
            continue
        rs = ratios[v]
        r = res['variants'][v]
        best_es = min(x['pos_err'] for x in _ok(r['rows'], 'stepping'))
        vv_top = max(_ok(r['rows'], 'verlet'), key=lambda x: x['param'])
        if min(rs) >= 1:
            words.append('%s: Verlet is %.3g to %.3g times cheaper at no larger position error, and its run at '
                         '%.2g s (0.9 of its stable step) is %.2g times more accurate than energy stepping\'s most '
                         'accurate run (h = %g J)' % (SHORT[v], min(rs), max(rs), vv_top['param'],
                                                    best_es / vv_top['pos_err'],
                                                    min(_ok(r['rows'], 'stepping'), key=lambda x: x['pos_err'])['param']))
        elif max(rs) < 1:
            words.append('%s: energy stepping is %.2g to %.2g times cheaper at no larger position error'
                         % (SHORT[v], 1 / max(rs), 1 / min(rs)))
        else:
            words.append('%s: mixed, CPU ratios energy stepping / Verlet from %.2g to %.2g' % (SHORT[v], min(rs),
                                                                                                max(rs)))
    if words:
        L.append('**What it shows:** ' + '; '.join(words) + '. The CPU ratios are lower bounds where that Verlet run '
                 'is the more accurate of the two. Energy stepping\'s events grow with the '
                 'minority as Verlet\'s steps do (the table of the shapes without it).\n')
    L.append('![run time against position error, three stiff-minority meshes](figures/bench_minority.png)\n')
    L.append('<!-- minority:end -->')
    return L


def write_report(ctx, res=None):
    res = res or load(ctx)
    if not res:
        return []
    figure(res, os.path.join(ctx.figs, 'bench_minority.png'))
    return section(ctx, res)


def splice(path, lines):
    splice_section(path, lines, 'minority', 'stiffness')
