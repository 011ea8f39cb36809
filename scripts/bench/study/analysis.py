"""Error measures and observables of one run.

(a) max |E(t) - E0| / N over the thermo samples;
(b) drift: least-squares slope of (E - E0)/N against time, and max |P(t) - P(0)| (linear momentum);
(c) trajectory error at the horizon t_short: RMS over atoms of |x(t_short) - x_ref(t_short)|
    (unwrapped positions in id order, the reference a much finer Verlet step);
(d) long-run observables with statistical error bars: temperature and pressure (block averages of
    the thermo samples, 10 blocks), first-peak height of g(r) (blocks of frames), diffusion
    coefficient from the MSD slope and the VDOS peak frequency (error bars from 5 groups of atoms).

g(r), MSD and VDOS come from terrace-analyze when the build has it (see ANALYZE below) and from
the numpy code here otherwise; each row records which one was used.
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
class Analyzer:
    """Structural and dynamical observables of one trajectory.

    terrace-analyze (the analysis program, branch feat-analyze) is used when the build directory
    has it: ANALYZE maps each observable to the command line tried; its output is read as a
    two-column table (x, y). If the program is absent, or a call fails, the numpy code above is
    used and the row says so ('numpy'). Adjust ANALYZE here once the program's interface is final.
    """
    ANALYZE = {
        'gr': ['rdf', '{traj}', '--output', '{out}'],
        'msd': ['msd', '{traj}', '--output', '{out}'],
        'vdos': ['vdos', '{traj}', '--output', '{out}'],
    }

    def __init__(self, build):
        exe = os.path.join(build, 'terrace-analyze')
        self.exe = exe if os.access(exe, os.X_OK) else None

    def _tool(self, what, traj):
        if not self.exe or not traj or not traj.endswith('.h5'):
            return None
        out = traj + '.' + what + '.txt'
        cmd = [self.exe] + [a.format(traj=traj, out=out) for a in self.ANALYZE[what]]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
            if p.returncode != 0 or not os.path.exists(out):
                return None
            a = np.loadtxt(out, comments='#', ndmin=2)
            return a[:, 0], a[:, 1]
        except (OSError, ValueError, subprocess.TimeoutExpired):
            return None

    def observables(self, scene, times, x, v, box, traj_path=None):
        """Returns a dict with gr_r, gr_peak(_se), D(_se), vdos(_se) and the method used."""
        out = {}
        dim = scene.dim
        if 'gr' in scene.observables and x is not None:
            rmax = min(0.5 * float(np.min(box[:dim])), 3.0 * (scene.pot.get('sigma', 2.55)))
            tool = self._tool('gr', traj_path)
            if tool is not None:
                r, g = tool
                i = int(np.argmax(g))
                out.update(gr_r=float(r[i]), gr_peak=float(g[i]), gr_peak_se=float('nan'), gr_method='terrace-analyze')
            else:
                r, gs = rdf(x, box, dim, rmax)
                rp, pk, se = first_peak(r, gs)
                out.update(gr_r=rp, gr_peak=pk, gr_peak_se=se, gr_method='numpy', gr_curve=(r, gs.mean(0)))
        if 'msd' in scene.observables and x is not None:
            out['D'], out['D_se'] = diffusion(times, x, dim)
            out['msd_method'] = 'numpy'
        if 'vdos' in scene.observables and v is not None:
            pk, se, f, s = vdos_peak(times, v, dim)
            out.update(vdos=pk, vdos_se=se, vdos_method='numpy')
            if f is not None:
                out['vdos_curve'] = (f, s / max(s.max(), 1e-300))
        return out
