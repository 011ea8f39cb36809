"""Error measures and observables of one run.

(a) max |E(t) - E0| / N over the thermo samples;
(b) drift: least-squares slope of (E - E0)/N against time, and max |P(t) - P(0)| (linear momentum);
(c) trajectory error at the horizon t_short: RMS over atoms of |x(t_short) - x_ref(t_short)|
    (unwrapped positions in id order, the reference a much finer Verlet step);
(d) long-run observables with statistical error bars: temperature and pressure (block averages of
    the thermo samples, 10 blocks), first-peak height of g(r) (blocks of frames), diffusion
    coefficient from the MSD slope and the VDOS peak frequency (error bars from 5 groups of atoms).

g(r), MSD and VDOS come from terrace-analyze (see Analyzer below); the numpy code here is the
fallback when the build has no terrace-analyze. Each row records which one was used (gr_method).
"""
import os
import subprocess

import numpy as np

N_BLOCKS = 10
N_GROUPS = 5


def block_mean(x, nb=N_BLOCKS):
    """Mean and standard error from nb contiguous blocks (NaN if too few samples)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if len(x) < 2 * nb:
        nb = max(2, len(x) // 2)
    if len(x) < 4:
        return (float(np.mean(x)) if len(x) else float('nan')), float('nan')
    m = len(x) // nb
    b = x[:m * nb].reshape(nb, m).mean(1)
    return float(np.mean(x)), float(np.std(b, ddof=1) / np.sqrt(nb))


def energy_metrics(th, natoms):
    """(a) and (b) from thermo columns (time, etotal, px, py, pz)."""
    out = {}
    if not th or 'etotal' not in th or len(th['etotal']) < 2:
        return out
    t, e = th['time'], th['etotal']
    de = (e - e[0]) / natoms
    out['max_de'] = float(np.nanmax(np.abs(de))) if np.all(np.isfinite(de)) else float('inf')
    if np.all(np.isfinite(de)) and t[-1] > t[0]:
        out['drift'] = float(np.polyfit(t - t[0], de, 1)[0])
    else:
        out['drift'] = float('nan')
    if all(k in th for k in ('px', 'py', 'pz')):
        p = np.stack([th['px'], th['py'], th['pz']], 1)
        out['max_dp'] = float(np.max(np.linalg.norm(p - p[0], axis=1)))
    return out


def thermo_observables(th, periodic):
    out = {}
    if not th:
        return out
    sel = slice(1, None)        # the first sample is the start state
    out['T'], out['T_se'] = block_mean(th['temp'][sel])
    if periodic and 'press' in th:
        out['P'], out['P_se'] = block_mean(th['press'][sel])
    return out


def frame_at(times, t, tol=1e-6):
    i = int(np.argmin(np.abs(times - t)))
    return i if abs(times[i] - t) <= tol * max(1.0, abs(t)) else None


def traj_error(times, x, ref_times, ref_x, t_short):
    i, j = frame_at(times, t_short), frame_at(ref_times, t_short)
    if i is None or j is None:
        return float('nan')
    d = x[i] - ref_x[j]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


# ------------------------------------------------------------------------------ g(r), MSD, VDOS
def rdf(x_frames, box, dim, rmax, nbins=200, max_centres=1000, max_frames=10):
    """g(r) per frame (minimum image; box edges along dim), averaged in blocks of frames."""
    F = len(x_frames)
    idx = np.unique(np.linspace(0, F - 1, min(F, max_frames)).round().astype(int))
    edges = np.linspace(0, rmax, nbins + 1)
    r = 0.5 * (edges[1:] + edges[:-1])
    L = np.asarray(box[:dim], float)
    vol = float(np.prod(L))
    shell = (4.0 / 3.0 * np.pi * (edges[1:] ** 3 - edges[:-1] ** 3)) if dim == 3 else np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    gs = []
    for f in idx:
        x = x_frames[f][:, :dim]
        n = len(x)
        nc = min(n, max_centres)
        h = np.zeros(nbins)
        for c0 in range(0, nc, 100):
            c = x[c0:min(nc, c0 + 100)]
            d = x[None, :, :] - c[:, None, :]
            d -= L * np.round(d / L)
            rr = np.sqrt(np.sum(d * d, axis=2)).ravel()
            rr = rr[(rr > 1e-9) & (rr < rmax)]
            h += np.histogram(rr, bins=edges)[0]
        gs.append(h / (nc * (n / vol) * shell))
    return r, np.array(gs)


def first_peak(r, gs):
    """Height of the first maximum of g(r): mean and standard error over the frames used."""
    g = gs.mean(0)
    i = int(np.argmax(g))
    lo, hi = max(0, i - 2), min(len(r), i + 3)
    peaks = gs[:, lo:hi].max(1)
    se = float(np.std(peaks, ddof=1) / np.sqrt(len(peaks))) if len(peaks) > 1 else float('nan')
    return float(r[i]), float(peaks.mean()), se


def diffusion(times, x, dim, groups=N_GROUPS, max_origins=50):
    """D from the slope of the MSD over lags in [T/4, T/2] (T the trajectory length), multiple
    time origins; mean and standard error over groups of atoms."""
    F, N = x.shape[0], x.shape[1]
    if F < 8:
        return float('nan'), float('nan')
    lags = np.arange(1, F // 2 + 1)
    step = max(1, (F // 2) // max_origins)
    msd = np.zeros((len(lags), N))
    for k, lag in enumerate(lags):
        o = np.arange(0, F - lag, step)
        d = x[o + lag, :, :dim] - x[o, :, :dim]
        msd[k] = np.mean(np.sum(d * d, axis=2), axis=0)
    dt = times[1] - times[0]
    sel = lags >= max(2, F // 8)
    Ds = []
    for g in np.array_split(np.arange(N), groups):
        m = msd[:, g].mean(1)
        slope = np.polyfit(lags[sel] * dt, m[sel], 1)[0]
        Ds.append(slope / (2 * dim))
    Ds = np.array(Ds)
    return float(Ds.mean()), float(Ds.std(ddof=1) / np.sqrt(len(Ds)))


def vdos_peak(times, v, dim, groups=N_GROUPS):
    """Frequency (1/time unit) of the maximum of the velocity power spectrum (Hann window, 3-bin
    smoothing, zero frequency excluded); mean and standard error over groups of atoms."""
    F, N = v.shape[0], v.shape[1]
    if F < 16:
        return float('nan'), float('nan'), None, None
    dt = times[1] - times[0]
    w = np.hanning(F)[:, None, None]
    freqs = np.fft.rfftfreq(F, dt)
    spec_all = None
    peaks = []
    for g in np.array_split(np.arange(N), groups):
        s = np.abs(np.fft.rfft(v[:, g, :dim] * w, axis=0)) ** 2
        s = s.sum(axis=(1, 2))
        s = np.convolve(s, np.ones(3) / 3, mode='same')
        spec_all = s if spec_all is None else spec_all + s
        peaks.append(freqs[1 + int(np.argmax(s[1:]))])
    peaks = np.array(peaks)
    return float(peaks.mean()), float(peaks.std(ddof=1) / np.sqrt(len(peaks))), freqs, spec_all


# ------------------------------------------------------------------------------ terrace-analyze
def write_h5md(path, times, x, v, edges, periodic):
    """A minimal H5MD file (the layout terrace-analyze reads, doc/analysis.md "What is read") from
    frames held in memory: used for the LAMMPS dumps and by the self-test."""
    import h5py
    F, N, D = x.shape
    with h5py.File(path, 'w') as f:
        p = f.create_group('particles/all')
        b = p.create_group('box')
        b.attrs['dimension'] = D
        b.attrs['boundary'] = np.array(['periodic' if periodic else 'none'] * D, dtype='S8')
        b.create_dataset('edges', data=np.asarray(edges[:D], float))
        for name, a in (('position', x), ('velocity', v)):
            if a is None:
                continue
            g = p.create_group(name)
            g.create_dataset('value', data=np.asarray(a[:, :, :D], float))
            g.create_dataset('step', data=np.arange(F, dtype=np.int64))
            g.create_dataset('time', data=np.asarray(times, float))


def _csv(path):
    """A terrace-analyze CSV: one header line of column names, then numbers."""
    with open(path) as f:
        names = [c.strip().split(' ')[0] for c in f.readline().split(',')]
    a = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    out = {}
    for i, n in enumerate(names):       # the first column of a name: D (file units) before D (cm^2/s)
        out.setdefault(n, a[:, i])
    return out


class Analyzer:
    """Structural and dynamical observables of one trajectory.

    With BUILD/terrace-analyze (doc/analysis.md) the observables come from it; the numpy code
    above is the fallback only when the executable is missing (a failing call is an error: the row
    records it instead of silently switching method). Method and error bars:

    - g(r) first peak: `--compute=rdf` on NB contiguous blocks of frames (`--first_frame`,
      `--last_frame`); the peak height is the block mean at the maximum of the mean curve, its error
      the standard error over the blocks;
    - D: `--compute=msd` with `--msd_blocks=NB` (fewer when a block would hold under 7 frames; D
      over the whole run, error = the tool's block standard error); longest lag half a block, fitted
      over its second half, at least 3 lags (`--msd_max_time`, `--msd_fit_start`, `--msd_fit_end`);
    - VDOS peak: `--compute=vdos` over the whole run (default correlation time, half the span, Hann
      window): the frequency of the maximum above zero; no error bar (one spectrum; its resolution
      1/(M dt) is recorded in vdos_res).

    Terrace rows pass their own H5MD file; LAMMPS rows (dumps) are written to a temporary H5MD file
    first, so that every method goes through the same code.
    """
    NB = 4

    def __init__(self, build):
        exe = os.path.join(build, 'terrace-analyze')
        self.exe = exe if os.access(exe, os.X_OK) else None
        self.method = 'terrace-analyze' if self.exe else 'numpy'

    def _run(self, traj, prefix, **keys):
        cmd = [self.exe, '--trajectory_file=%s' % traj, '--output_prefix=%s' % prefix]
        cmd += ['--%s=%s' % (k, v) for k, v in keys.items()]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if p.returncode != 0:
            raise RuntimeError('terrace-analyze failed (%s): %s' % (' '.join(cmd), (p.stdout + p.stderr).strip()[-400:]))
        return p.stdout

    def _gr(self, traj, F, rmax, pre):
        nb = min(self.NB, F)
        bounds = np.linspace(0, F, nb + 1).round().astype(int)
        curves = []
        for b in range(nb):
            self._run(traj, pre, compute='rdf', rdf_r_max='%.10g' % rmax, rdf_bins=200,
                      first_frame=bounds[b] + 1, last_frame=bounds[b + 1])
            c = _csv(pre + '_rdf.csv')
            curves.append(c['g'])
        gs = np.array(curves)
        rp, pk, se = first_peak(c['r'], gs)
        return rp, pk, se, (c['r'], gs.mean(0))

    def _msd(self, traj, F, dt, pre):
        nb = max(2, min(self.NB, F // 7))          # fewer blocks for short runs: the fit needs >= 3 lags
        m = (F // nb - 1) // 2                     # longest lag (frames): a block holds >= 2 m + 1 frames
        if m < 3:
            return float('nan'), float('nan')
        start = min(0.5 * m, m - 2)                # the second half of the lags, at least 3 of them
        self._run(traj, pre, compute='msd', msd_blocks=nb, msd_max_time='%.10g' % (m * dt),
                  msd_fit_start='%.10g' % (start * dt), msd_fit_end='%.10g' % (m * dt))
        d = _csv(pre + '_diffusion.csv')
        return float(d['D'][0]), float(d['D_stderr_blocks'][0])

    def _vdos(self, traj, dt, pre):
        out = self._run(traj, pre, compute='vdos')
        c = _csv(pre + '_vdos.csv')
        f, g = c['frequency'], c['vdos']
        sel = f > 0
        i = int(np.argmax(np.where(sel, g, -np.inf)))
        return float(f[i]), (f, g / max(g.max(), 1e-300)), out

    def observables(self, scene, times, x, v, box, traj_path=None):
        """Returns a dict with gr_r, gr_peak(_se), D(_se), vdos(_se) and the method used."""
        out = {}
        dim = scene.dim
        want = [k for k in ('gr', 'msd', 'vdos') if k in scene.observables]
        if not want or x is None:
            return out
        rmax = min(0.5 * float(np.min(box[:dim])), 3.0 * (scene.pot.get('sigma', 2.55)))
        if self.exe is None:
            return self._numpy(scene, times, x, v, box, rmax, want)
        import tempfile
        tmp = tempfile.mkdtemp(prefix='study_analyze.')
        try:
            traj = traj_path
            if not traj or not os.path.exists(traj):
                traj = os.path.join(tmp, 'frames.h5')
                write_h5md(traj, times, x, v, box, scene.periodic)
            pre = os.path.join(tmp, 'a')
            F, dt = len(times), float(times[1] - times[0])
            if 'gr' in want:
                rp, pk, se, curve = self._gr(traj, F, rmax, pre)
                out.update(gr_r=rp, gr_peak=pk, gr_peak_se=se, gr_curve=curve)
            if 'msd' in want:
                out['D'], out['D_se'] = self._msd(traj, F, dt, pre)
            if 'vdos' in want and v is not None:
                pk, curve, _ = self._vdos(traj, dt, pre)
                out.update(vdos=pk, vdos_se=float('nan'), vdos_curve=curve)
            out['gr_method'] = 'terrace-analyze'
        finally:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)
        return out

    @staticmethod
    def _numpy(scene, times, x, v, box, rmax, want):
        out = {'gr_method': 'numpy'}
        dim = scene.dim
        if 'gr' in want:
            r, gs = rdf(x, box, dim, rmax)
            rp, pk, se = first_peak(r, gs)
            out.update(gr_r=rp, gr_peak=pk, gr_peak_se=se, gr_curve=(r, gs.mean(0)))
        if 'msd' in want:
            out['D'], out['D_se'] = diffusion(times, x, dim)
        if 'vdos' in want and v is not None:
            pk, se, f, s = vdos_peak(times, v, dim)
            out.update(vdos=pk, vdos_se=se)
            if f is not None:
                out['vdos_curve'] = (f, s / max(s.max(), 1e-300))
        return out
