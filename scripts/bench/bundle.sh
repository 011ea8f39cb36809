#!/usr/bin/env bash
# Carry Terrace, LAMMPS and Open MPI to a machine that has none of them (the 16-core machine that the
# workplace's device tool lends, which cannot install packages), to run scripts/bench/scaling.sh there.
#
#   scripts/bench/bundle.sh pack DIR    (here, after scripts/install_deps.sh --bench) builds Terrace twice, for
#       x86-64-v3 (AVX2) and x86-64-v4 (AVX-512), into DIR/build-v3 and DIR/build-v4, and packs into
#       DIR/bundle.tar.xz: both binaries, /usr/bin/lmp, GROMACS's gmx and gmx_d with their data
#       (share/gromacs), GNU time, Open MPI's mpirun with its plugins, help files and settings, every
#       shared library these load except the C library's own, and the EAM files of the benchmarks.
#   scripts/bench/bundle.sh run DIR COMMAND...   (there) unpacks DIR/bundle.tar.xz to /tmp/terrace-bundle,
#       sets PATH, LD_LIBRARY_PATH, OPAL_PREFIX (Open MPI relocated), TERRACE (the x86-64-v4 binary where
#       the CPU has AVX-512, else x86-64-v3), LMP, EAM_FILE, LAMMPS_POTENTIALS and GNU_TIME, and runs
#       COMMAND: scaling.sh, anchors.sh (INSTALL=0, PARTS lj, eam, types: anchors from the bundle), or any
#       script that takes the binary from $TERRACE (es_cost.py --terrace "$TERRACE", where python3 is).
#   scripts/bench/bundle.sh check DIR   (here) runs small scaling.sh and anchors.sh passes from the bundle with the
#       system's Open MPI, LAMMPS, GROMACS and libraries hidden (a private mount namespace; needs root), to show
#       that nothing outside the bundle is used.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
cmd="${1:-}"; dir="${2:-}"
[[ -n "$cmd" && -n "$dir" ]] || { sed -n '2,15p' "${BASH_SOURCE[0]}" >&2; exit 2; }
mkdir -p "$dir"; dir="$(cd "$dir" && pwd)"
arch=x86_64-linux-gnu
ompi_plugins=/usr/lib/$arch/openmpi/lib/openmpi3
skip_plugins='ucx|ofi|openib|psm|uct|verbs|pmix_flux|schizo_flux|schizo_jsm'
potdir=/usr/share/lammps/potentials   # the EAM files of scaling.sh and anchors.sh (eam, types)
pots="Cu_u3.eam CuNi.eam.alloy Fe_mm.eam.fs Cu_mishin1.eam.alloy"
glibc='^(linux-vdso|ld-linux|libc|libm|libmvec|libpthread|libdl|librt|libresolv|libutil)\.so'

case "$cmd" in
pack)
    for v in v3 v4; do
        cmake -S "$repo" -B "$dir/build-$v" -DCMAKE_BUILD_TYPE=Release -DTERRACE_TESTS=OFF \
              -DTERRACE_MARCH=x86-64-$v > "$dir/build-$v.log" 2>&1
        cmake --build "$dir/build-$v" -j "$(nproc)" --target terrace >> "$dir/build-$v.log" 2>&1 \
            || { tail -20 "$dir/build-$v.log" >&2; exit 1; }
    done
    stage="$dir/stage"; rm -rf "$stage"; mkdir -p "$stage"/{bin,lib,pot}
    b="$stage/ompi"   # Open MPI's tree under its relocated prefix, as Debian lays it out under /usr
    mkdir -p "$b/bin" "$b/lib/$arch/openmpi/lib/openmpi3" "$b/share" "$b/etc"
    cp "$dir/build-v3/terrace" "$stage/bin/terrace-v3"; cp "$dir/build-v4/terrace" "$stage/bin/terrace-v4"
    cp /usr/bin/lmp "$stage/bin/lmp"; for p in $pots; do cp "$potdir/$p" "$stage/pot/"; done; cp /usr/bin/time "$stage/bin/time"
    # GROMACS finds its data (share/gromacs) beside the binary's folder, as under /usr
    mkdir -p "$stage/gmx/bin" "$stage/gmx/share"
    cp /usr/bin/gmx /usr/bin/gmx_d "$stage/gmx/bin/"; cp -r /usr/share/gromacs "$stage/gmx/share/gromacs"
    cp "$(readlink -f /usr/bin/orterun)" "$b/bin/orterun"; ln -s orterun "$b/bin/mpirun"
    cp "$(readlink -f /usr/bin/orted)" "$b/bin/orted"
    cp -r /usr/share/openmpi "$b/share/openmpi"; cp /etc/openmpi/openmpi-mca-params.conf "$b/etc/"
    [[ -d /usr/lib/$arch/pmix2/share/pmix ]] && mkdir -p "$b/share/pmix" && cp -r /usr/lib/$arch/pmix2/share/pmix/. "$b/share/pmix/"
    objs=("$stage/bin/terrace-v3" "$stage/bin/terrace-v4" "$stage/bin/lmp" "$b/bin/orterun" "$b/bin/orted"
          "$stage/gmx/bin/gmx" "$stage/gmx/bin/gmx_d")
    for f in "$ompi_plugins"/*.so; do
        [[ "$(basename "$f")" =~ $skip_plugins ]] && continue
        cp "$f" "$b/lib/$arch/openmpi/lib/openmpi3/"; objs+=("$b/lib/$arch/openmpi/lib/openmpi3/$(basename "$f")")
    done
    for f in "${objs[@]}"; do
        ldd "$f" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}'
    done | sort -u | while read -r name path; do
        [[ "$name" =~ $glibc ]] && continue
        cp -L "$path" "$stage/lib/$name"
    done
    git -C "$repo" rev-parse --short HEAD > "$stage/commit" 2>/dev/null || echo unknown > "$stage/commit"
    tar -C "$stage" -cJf "$dir/bundle.tar.xz" .
    echo "bundle: $dir/bundle.tar.xz ($(du -h "$dir/bundle.tar.xz" | cut -f1); $(ls "$stage/lib" | wc -l) libraries)"
    ;;
run)
    shift 2
    t=/tmp/terrace-bundle
    rm -rf $t; mkdir -p $t; tar -C $t -xJf "$dir/bundle.tar.xz"   # afresh: a warm machine may hold an older one
    export PATH="$t/ompi/bin:$t/bin:$t/gmx/bin:$PATH" LD_LIBRARY_PATH="$t/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    export OPAL_PREFIX="$t/ompi" PMIX_PREFIX="$t/ompi" OMPI_MCA_mca_base_param_files="$t/ompi/etc/openmpi-mca-params.conf"
    export OMPI_MCA_mca_base_component_show_load_errors=0 PMIX_MCA_pcompress_base_silence_warning=1   # (no zlib for PMIx there)
    if grep -q -w avx512f /proc/cpuinfo && grep -q -w avx512bw /proc/cpuinfo && grep -q -w avx512vl /proc/cpuinfo \
       && grep -q -w avx512dq /proc/cpuinfo && grep -q -w avx512cd /proc/cpuinfo; then
        export TERRACE="$t/bin/terrace-v4"; else export TERRACE="$t/bin/terrace-v3"; fi
    export LMP="$t/bin/lmp" MPIRUN="$t/ompi/bin/mpirun" EAM_FILE="$t/pot/Cu_u3.eam" LAMMPS_POTENTIALS="$t/pot" GNU_TIME="$t/bin/time" BUNDLE_COMMIT="$(cat $t/commit)"
    "$@"
    ;;
check)
    [[ $(id -u) == 0 ]] || { echo "bundle.sh check: needs root (mount namespace)" >&2; exit 1; }
    exec unshare -m bash -c '
        set -e; mkdir -p /tmp/bundle-empty; touch /tmp/bundle-empty.file
        for d in /usr/lib/'$arch'/openmpi /usr/lib/'$arch'/pmix2 /usr/share/openmpi /etc/openmpi /usr/share/lammps \
                 /usr/lib/'$arch'/hwloc /usr/share/gromacs; do [[ -d $d ]] && mount --bind /tmp/bundle-empty $d; done
        for f in /usr/bin/mpirun /usr/bin/orterun /usr/bin/orted /usr/bin/lmp /usr/bin/gmx /usr/bin/gmx_d /usr/bin/time; do mount --bind /tmp/bundle-empty.file $f; done
        tar -tJf "'"$dir"'/bundle.tar.xz" | sed -n "s|^\./lib/\(..*\)|\1|p" | while read -r l; do
            n=/usr/lib/'$arch'/$l; if [[ -e $n ]]; then mount --bind /tmp/bundle-empty.file $n; fi; done
        echo "hidden: the system'"'"'s Open MPI, PMIx, LAMMPS, GROMACS, GNU time and every library the bundle carries"
        LJ_STEPS=20 LJ_EVENTS=10 EAM_STEPS=10 EAM_EVENTS=5 KINDS=strong MPI_FLAGS="--oversubscribe" \
            bash "'"$here"'/bundle.sh" run "'"$dir"'" bash "'"$here"'/scaling.sh" 1,2 /tmp/bundle-check
        INSTALL=0 PARTS=lj,eam,types REPEAT=1 bash "'"$here"'/bundle.sh" run "'"$dir"'" bash "'"$here"'/anchors.sh" 20 10'
    ;;
*) echo "bundle.sh: unknown command '$cmd' (pack, run, check)" >&2; exit 2 ;;
esac
