#!/usr/bin/env bash
# Files users really have: a LAMMPS data file as write_data writes it by
# default ('Pair Coeffs' section) and with 'pair ij' ('PairIJ Coeffs') is read, its coefficients are
# checked against &potential, and the run gives the same step-0 energy and forces as the 'nocoeff'
# file (byte-identical thermo line and forces file); coefficients that disagree with the deck are
# an error naming the file; a data file with molecular topology is refused clearly.
#
# usage: write_data_default.sh TERRACE_BIN OUTPUT_DIR     (LMP: the LAMMPS executable, default lmp)
# Exit status: 0 pass, 77 skipped (no LAMMPS), 1 failure.
set -u
terrace=$(readlink -f "$1")
out=$2
LMP=${LMP:-lmp}
if ! command -v "$LMP" > /dev/null 2>&1; then
    echo "SKIP: LAMMPS executable '$LMP' not found (Debian package 'lammps')" >&2
    exit 77
fi
rm -rf "$out" && mkdir -p "$out" && cd "$out" || exit 1

# a two-type LJ liquid start: geometric mixing for the 1-2 pair, as Terrace mixes
cat > in.make << 'EOF'
units lj
atom_style atomic
boundary p p p
lattice fcc 0.8442
region box block 0 5 0 5 0 5
create_box 2 box
create_atoms 1 box
set type 1 type/fraction 2 0.3 12345
mass * 1.0
velocity all create 1.0 4928 loop geom
pair_style lj/cut 2.5
pair_coeff 1 1 1.0 1.0
pair_coeff 2 2 0.8 1.1
run 0
write_data default.data
write_data pairij.data pair ij
write_data nocoeff.data nocoeff
EOF
"$LMP" -screen none -log lammps.log -in in.make || { echo "FAIL: LAMMPS could not write the data files"; exit 1; }
grep -q '^Pair Coeffs' default.data || { echo "FAIL: default.data has no Pair Coeffs section"; exit 1; }
grep -q '^PairIJ Coeffs' pairij.data || { echo "FAIL: pairij.data has no PairIJ Coeffs section"; exit 1; }

deck() { # name data epsilon22
    cat > "$1.nml" << EOF
&run units='lj', n_steps=0 /
&system read_data='$2' /
&potential style='lj', epsilon(1,1)=1.0, epsilon(2,2)=$3, sigma(1,1)=1.0, sigma(2,2)=1.1, cutoff=2.5 /
&integrator dt=0.005 /
&output thermo_every=1, thermo_file='$1.csv', forces_file='$1.forces' /
EOF
}
fail=0
for name in nocoeff default pairij; do
    deck "$name" "$name.data" 0.8
    if ! "$terrace" "$name.nml" > "$name.log" 2>&1; then
        echo "FAIL: $name.data: terrace exited non-zero: $(grep 'error' "$name.log" | head -n 1)"
        fail=1
    fi
done
[ "$fail" = 0 ] || exit 1
for name in default pairij; do
    grep -q 'agree with &potential' "$name.log" || { echo "FAIL: $name: no note that the coefficients agree"; fail=1; }
    a=$(sed -n 2p nocoeff.csv | cut -d, -f1-7)
    b=$(sed -n 2p "$name.csv" | cut -d, -f1-7)
    if [ "$a" != "$b" ]; then
        echo "FAIL: $name: step-0 thermo differs from nocoeff: '$b' vs '$a'"; fail=1
    fi
    if ! cmp -s <(tail -n +2 nocoeff.forces) <(tail -n +2 "$name.forces"); then
        echo "FAIL: $name: step-0 forces differ from nocoeff"; fail=1
    fi
    echo "ok: $name.data: step-0 pe $(echo "$b" | cut -d, -f4), forces of $(($(wc -l < "$name.forces") - 2)) atoms identical to nocoeff"
done

# coefficients that disagree with the deck: one error line naming the file, no outputs
deck mismatch default.data 0.7
"$terrace" mismatch.nml > mismatch.log 2> mismatch.err
rc=$?
if [ "$rc" = 0 ] || ! grep -q '^terrace: error: default.data: &system: read_data: .*disagree' mismatch.err \
    || [ -e mismatch.csv ] || [ -e mismatch.forces ]; then
    echo "FAIL: disagreeing Pair Coeffs: exit $rc, stderr: $(head -n 1 mismatch.err)"; fail=1
else
    echo "ok: disagreeing coefficients refused: $(head -n 1 mismatch.err)"
fi

# molecular topology: refused, naming the line
sed 's/^500 atoms$/500 atoms\n3 bonds/' nocoeff.data > bonds.data
deck bonds bonds.data 0.8
"$terrace" bonds.nml > bonds.log 2> bonds.err
rc=$?
if [ "$rc" = 0 ] || ! grep -q 'bonds.data:4: &system: read_data: .*molecular topology' bonds.err; then
    echo "FAIL: a data file with bonds: exit $rc, stderr: $(head -n 1 bonds.err)"; fail=1
else
    echo "ok: molecular topology refused: $(head -n 1 bonds.err)"
fi
exit $fail
