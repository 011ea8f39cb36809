"""terrace_tools: read what Terrace writes, and what the benchmarks' other codes write.

    from terrace_tools import summary, thermo, h5md, atoms, lammps, gromacs, plotting
    s = summary.read("run.summary.json");  summary.get(s, "timing/loop_time_s")
    t = thermo.read("thermo.csv");         t["etotal"]
    u = h5md.universe("traj.h5")           # an MDAnalysis Universe with types and masses

Install: ``pip install -e scripts`` (in a virtual environment), or put ``scripts`` on PYTHONPATH.
"""
__version__ = "0.1.0"
