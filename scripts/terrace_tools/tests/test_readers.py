"""The readers of other codes' outputs, on small texts in their formats; the thermo reader."""
import numpy as np
import pytest

from terrace_tools import gromacs, lammps, thermo

LAMMPS_LOG = """LAMMPS (2 Aug 2023)
Step Time Temp PotEng KinEng TotEng Press
       0   0              1.44  -6.7733681  2.1571962 -4.6161719 -5.0196707
     100   0.5   0.75   -5.76  1.12  -4.64  0.62
Loop time of 1.25 on 1 procs for 100 steps with 4000 atoms

Section |  min time  |  avg time  |  max time  |%varavg| %total
---------------------------------------------------------------
Pair    | 1.0        | 1.0        | 1.0        |   0.0 | 80.00
Neigh   | 0.125      | 0.125      | 0.125      |   0.0 | 10.00
Comm    | 0.05       | 0.05       | 0.05       |   0.0 |  4.00
Output  | 0.01       | 0.01       | 0.01       |   0.0 |  0.80
Modify  | 0.04       | 0.04       | 0.04       |   0.0 |  3.20
Other   |            | 0.025      |            |       |  2.00
"""

DUMP = """ITEM: TIMESTEP
10
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS pp pp pp
0 1
0 1
0 1
ITEM: ATOMS id xu yu zu vx vy vz
2 0.5 0.6 0.7 1 2 3
1 0.1 0.2 0.3 4 5 6
"""

MD_LOG = """               Core t (s)   Wall t (s)        (%)
       Time:       12.345       12.400       99.6
                 (ns/day)    (hour/ns)
Performance:      139.361        0.172
"""

XVG = """# gmx energy
@    title "GROMACS Energies"
@ s0 legend "Potential"
@ s1 legend "Kinetic En."
0.000000  -100.5  50.25
0.002000  -100.0  49.75
"""


def test_lammps_log():
    r = lammps.parse_log(LAMMPS_LOG)
    assert r["loop"] == 1.25 and r["n"] == 100 and r["nprocs"] == 1
    assert (r["pair"], r["neigh"], r["comm"], r["output"], r["other"]) == (1.0, 0.125, 0.05, 0.01, 0.025)
    assert list(r["thermo"]["etotal"]) == [-4.6161719, -4.64]
    assert list(r["thermo"]["step"]) == [0, 100]


def test_lammps_dump_sorted_by_id(tmp_path):
    p = tmp_path / "d.txt"
    p.write_text(DUMP)
    t, c = lammps.read_dump(str(p), dt=0.005)
    assert t.tolist() == [0.05]
    assert c["id"][0].tolist() == [1, 2] and c["xu"][0].tolist() == [0.1, 0.5] and c["vz"][0].tolist() == [6, 3]


def test_lammps_data_roundtrip(tmp_path):
    p = tmp_path / "start.data"
    x = np.array([[0.1, 0.2, 0.3], [1.0, 1.5, 2.0]])
    lammps.write_data(str(p), [1, 2], x, -x, [0, 0, 0], [3, 3, 3], [1.0, 2.5])
    text = p.read_text().splitlines()
    assert "2 atoms" in text and "2 atom types" in text
    i = text.index("Atoms # atomic")
    assert [float(w) for w in text[i + 3].split()] == [2, 2, 1.0, 1.5, 2.0]


def test_gromacs():
    r = gromacs.parse_md_log(MD_LOG)
    assert (r["core_s"], r["wall_s"], r["percent"], r["ns_per_day"], r["hours_per_ns"]) == \
        (12.345, 12.4, 99.6, 139.361, 0.172)


def test_xvg(tmp_path):
    p = tmp_path / "e.xvg"
    p.write_text(XVG)
    legends, a = gromacs.read_xvg(str(p))
    assert legends == ["Potential", "Kinetic En."] and a.shape == (2, 3) and a[1, 1] == -100.0


def test_thermo_csv(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("step,time,etotal,px,py,pz\n0, 0.0, -1.0, 0, 0, 0\n10, 0.05, -0.99, 3, 4, 0\n")
    t = thermo.read(str(p))
    assert list(t) == ["step", "time", "etotal", "px", "py", "pz"]
    assert thermo.energy_drift(t, 2) == pytest.approx(0.01 / (2 * 0.05))
    assert thermo.momentum_change(t) == 5.0
    assert thermo.read(str(tmp_path / "missing.csv")) == {}


def test_thermo_plot(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("step,time,temp,etotal\n0, 0.0, 184.0, -1.0\n10, 1.0, 120.0, -0.99\n20, 2.0, 95.0, -0.98\n")
    out = tmp_path / "t.png"
    assert thermo.plot(str(p), ["temp", "etotal"], str(out)) == str(out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000
    with pytest.raises(SystemExit, match="no column press"):
        thermo.plot(str(p), ["press"], str(out))


def test_analysis_csv_and_plotting_save(tmp_path):
    from terrace_tools import analysis
    from terrace_tools.plotting import DPI, plt, save
    p = tmp_path / "x_rdf.csv"
    p.write_text("# g(r) of 4 frames\nr,g\n0.5,0.0\n1.0,2.5\n1.5,1.0\n")
    t = analysis.read(str(p))
    assert list(t) == ["r", "g"] and t["g"].tolist() == [0.0, 2.5, 1.0]
    assert analysis.array(str(p)).shape == (3, 2)
    fig, ax = plt.subplots(figsize=(2.0, 1.0))
    ax.plot(t["r"], t["g"])
    out = save(fig, str(tmp_path / "sub" / "x.png"))
    png = open(out, "rb").read()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert (width, height) == (2 * DPI, 1 * DPI)
    assert not plt.get_fignums()                 # closed
