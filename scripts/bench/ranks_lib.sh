# Sourced by scaling.sh and argon_weak.sh: the rank list, how ranks are bound, the weak-scaling boxes.

# ranks_setup RANKS (comma list): sets plist (array), pmax, ncores, phys (lscpu's sockets x cores per
# socket) and, unless the caller set it (even empty), MPI_FLAGS: a rank per core where there are
# enough cores, else per hardware thread, else oversubscribed.
ranks_setup() {
    IFS=, read -r -a plist <<< "$1"
    pmax=0; for p in "${plist[@]}"; do (( p > pmax )) && pmax=$p; done
    ncores=$(getconf _NPROCESSORS_ONLN)   # not nproc: it honours OMP_NUM_THREADS
    phys=$(lscpu 2>/dev/null | awk -F: '/^Socket\(s\)/{s=$2} /^Core\(s\) per socket/{c=$2} END{if (s*c > 0) print s*c; else print 0}')
    if [[ -z "${MPI_FLAGS+x}" ]]; then
        if (( phys >= pmax )); then MPI_FLAGS="--map-by core --bind-to core"
        elif (( ncores >= pmax )); then MPI_FLAGS="--use-hwthread-cpus --map-by hwthread --bind-to hwthread"
        else MPI_FLAGS="--oversubscribe --bind-to none"; fi
    fi
}

# weak_factors P: copies of the one-rank box along x, y, z for P ranks: doubled along the shortest
# axis for each factor 2 of P, then along x by what remains (odd P).
weak_factors() {
    local p=$1 a=1 b=1 c=1
    while (( p % 2 == 0 )); do
        if (( a <= b && a <= c )); then a=$((a * 2)); elif (( b <= c )); then b=$((b * 2)); else c=$((c * 2)); fi
        p=$((p / 2))
    done
    echo "$((a * p)) $b $c"
}
