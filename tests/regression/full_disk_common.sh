# Sourced by the full-disk tests (full_disk_small.sh, full_disk_hdf5.sh) with their arguments
# TERRACE_BIN OUTPUT_DIR: sets terrace, out and mnt (a 64 KiB tmpfs mounted under OUTPUT_DIR,
# unmounted at exit), or exits 77 (SKIP) where the mount is not allowed (it needs root).
terrace=$(readlink -f "$1")
out=$(mkdir -p "$2" && cd "$2" && pwd)
mnt=$out/full
mkdir -p "$mnt"
if ! mount -t tmpfs -o size=64k tmpfs "$mnt" 2> /dev/null; then
    echo "SKIP: cannot mount a small tmpfs here (needs root); the full-disk test did not run" >&2
    exit 77
fi
trap 'umount "$mnt" 2> /dev/null' EXIT
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
