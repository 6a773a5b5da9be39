# psys import lammps (docs/cli.md "psys import"): a hand-written LAMMPS data
# file becomes the scene it describes (particles in atom-id order, masses by
# type, box, lennard-jones pair force, velocity Verlet), its energies are the
# analytic ones, and every malformed file is refused with status 2, a
# one-line message naming the line, and no output written. Needs no LAMMPS
# (tests/cli/lammps.sh compares with LAMMPS itself).
. "$(dirname "$0")/lib.sh"

# Two atoms, ids out of order, type 2 given outside the box (x = 11.5 in
# [-5, 5): wraps to 1.5), with image flags on one line only, comments, zero
# tilt, two types with the same mass and coefficients written differently.
cat >good.data <<'EOF'
two atoms, hand-written (LAMMPS data file format)

2 atoms
2 atom types

-5 5 xlo xhi
0 10 ylo yhi
0 10 zlo zhi
0 0 0 xy xz yz

Masses

1 2.0
2 2 # the same mass, written differently

Pair Coeffs # lj/cut

1 1.0 1.0
2 1 1

Atoms # atomic

7 2 11.5 5 5 -1 0 0
3 1 0.25 5 5

Velocities

7 0 0 0.5
3 1 0 0
EOF

psys import lammps good.data --out good.json
expect_rc 0 "import good.data"
expect_stdout_empty "import good.data"
expect_stderr_empty "import good.data"
psys check good.json
expect_rc 0 "check the imported scene"
field() { sed -n "s/^$1: //p" out.txt; }
expect_eq 3 "$(field dim)" "dim"
expect_eq 2 "$(field particles)" "particles"
expect_eq verlet "$(field integrator)" "default integrator"
expect_eq 0.0050000000000000001 "$(field dt)" "default dt"
expect_eq 100 "$(field steps)" "default steps"
# KE = ½·2·1² + ½·2·0.5² = 1.25; U = 4[(1/1.25)¹² − (1/1.25)⁶] at r = 1.5 − 0.25.
expect_eq 1.25 "$(field kinetic)" "kinetic energy"
expect_near "$(field potential)" "$(awk 'BEGIN { s = 1 / 1.25; s6 = s^6; printf "%.17g", 4 * (s6 * s6 - s6) }')" 1e-14 "LJ energy"
psys run good.json --steps 0 --out t.csv
expect_rc 0 "run 0 steps"
expect_eq "0,0,0,0.25,5,5,1,0,0" "$(sed -n 2p t.csv)" "particle 0 is atom id 3"
expect_eq "0,0,1,1.5,5,5,0,0,0.5" "$(sed -n 3p t.csv)" "particle 1 is atom id 7, wrapped into the box"
expect_eq 1 "$(grep -c '"law":[[:space:]]*"lennard-jones"' good.json)" "lennard-jones pair force"
expect_eq 1 "$(grep -c '"cutoff":[[:space:]]*2.5,' good.json)" "default cutoff 2.5 sigma"
expect_eq 1 "$(grep -c '"skin":[[:space:]]*0.3' good.json)" "default skin 0.3"
expect_eq 1 "$(grep -c '"method":[[:space:]]*"grid"' good.json)" "grid method"

# Flags, the = form, and --out - (the scene on standard output).
psys import lammps good.data --out - --cutoff=2 --skin 0 --shift --dt 0.001 --steps 7 --integrator rk4
expect_rc 0 "import with flags to stdout"
cp out.txt flags.json
psys check flags.json
expect_eq "rk4 0.001 7" "$(field integrator) $(field dt) $(field steps)" "--integrator, --dt, --steps"
expect_eq 1 "$(grep -c '"cutoff":[[:space:]]*2,' flags.json)" "--cutoff"
expect_eq 1 "$(grep -c '"shift":[[:space:]]*true' flags.json)" "--shift"
expect_eq 1 "$(grep -c '"skin":[[:space:]]*0$' flags.json)" "--skin 0"

# Standard input; PairIJ Coeffs with a cutoff column; no Velocities section.
sed -e 's/^Pair Coeffs # lj\/cut/PairIJ Coeffs # lj\/cut/' -e 's/^1 1.0 1.0$/1 1 1.0 1.0 2.2/' \
    -e 's/^2 1 1$/1 2 1 1 2.2\n2 2 1 1 2.2/' -e '/^Velocities/,$d' good.data >ij.data
psys_in ij.data import lammps - --out ij.json
expect_rc 0 "PairIJ Coeffs from standard input"
psys check ij.json
expect_eq 0 "$(field kinetic)" "no Velocities: at rest"
expect_eq 1 "$(grep -c '"cutoff":[[:space:]]*2.2,' ij.json)" "cutoff from PairIJ Coeffs"

# Different coefficients per type are refused, unless --epsilon/--sigma replace them.
sed 's/^2 1 1$/2 1.5 1/' good.data >types.data
psys import lammps types.data --out types.json --epsilon 0.5 --sigma 1.1
expect_rc 0 "--epsilon/--sigma over differing types"
expect_eq 1 "$(grep -c '"epsilon":[[:space:]]*0.5,' types.json)" "--epsilon"
expect_eq 1 "$(grep -c '"cutoff":[[:space:]]*2.75' types.json)" "cutoff 2.5 x --sigma"

# bad SED-SCRIPT EXPECTED-STDERR: good.data edited is refused (status 2,
# exactly that message, nothing written, an existing --out file untouched).
bad() {
    sed "$1" good.data >bad.data
    sentinel out.json
    psys import lammps bad.data --out out.json
    expect_rc 2 "bad data ($1)"
    expect_stderr "$2" "bad data ($1)"
    expect_untouched out.json "bad data ($1)"
    expect_no_tmp "bad data ($1)"
}
bad 's/^0 0 0 xy xz yz/0.5 0 0 xy xz yz/' \
    'psys: bad.data: line 9: a triclinic box (non-zero tilt factors xy xz yz) cannot be imported: psys boxes are orthogonal (got "0.5 0 0 xy xz yz")'
bad 's/^2 1 1$/2 1.5 1/' \
    'psys: bad.data: line 19: these lj/cut coefficients (epsilon 1.5, sigma 1) differ from those of line 18 (epsilon 1, sigma 1): psys has one Lennard-Jones law for all atoms (give --epsilon and --sigma to use one) (got "2 1.5 1")'
bad 's/^2 1 1$/2 1 1 3/' \
    'psys: bad.data: line 19: this cutoff differs from that of line 18: psys has one cutoff for all atoms (give --cutoff to use one) (got "2 1 1 3")'
bad 's/^Atoms # atomic/Atoms # full/' \
    'psys: bad.data: line 21: atom style full cannot be imported: psys imports atom_style atomic only (got "Atoms # full")'
bad 's/^Pair Coeffs # lj\/cut/Pair Coeffs # morse/' \
    'psys: bad.data: line 16: pair style morse cannot be imported: psys imports pair_style lj/cut only (got "Pair Coeffs # morse")'
bad 's/^2 atom types/2 atom types\n1 bonds/' \
    'psys: bad.data: line 5: psys imports atom_style atomic systems only (no bonds) (got "1 bonds")'
bad 's/^Masses/Bonds/' \
    'psys: bad.data: line 11: this section cannot be imported: psys imports atom_style atomic systems with pair_style lj/cut (got "Bonds")'
bad 's/^3 1 0.25 5 5$/7 1 0.25 5 5/' \
    'psys: bad.data: line 24: atom id 7 is used twice (also on line 23)'
bad 's/^3 1 0 0$/4 1 0 0/' \
    'psys: bad.data: line 29: no atom has id 4 (got "4 1 0 0")'
bad '/^3 1 0.25 5 5$/d' \
    'psys: bad.data: line 25: the Atoms section ends after 1 of 2 atoms (got "Velocities")'
bad '/^3 1 0 0$/d' \
    'psys: bad.data: the file ends in the Velocities section after 1 of 2 atoms'
bad 's/^3 1 0.25 5 5$/3 1 0.25 5e 5/' \
    'psys: bad.data: line 24: the position must be three finite numbers (got "3 1 0.25 5e 5")'
bad 's/^3 1 0.25 5 5$/3 1 0.25 nan 5/' \
    'psys: bad.data: line 24: the position must be three finite numbers (got "3 1 0.25 nan 5")'
bad 's/^7 2 11.5 5 5 -1 0 0/7 2 11.5 5 5 -1 0/' \
    'psys: bad.data: line 23: an Atoms line of atom_style atomic is "ID TYPE X Y Z" or "ID TYPE X Y Z IX IY IZ" (got "7 2 11.5 5 5 -1 0")'
bad 's/^3 1 0.25 5 5$/3 3 0.25 5 5/' \
    'psys: bad.data: line 24: the atom type must be an integer between 1 and 2 (got "3 3 0.25 5 5")'
bad 's/^2 2 # the same/2 -2 # the same/' \
    'psys: bad.data: line 14: the mass must be > 0 (got "2 -2 # the same mass, written differently")'
bad '/^Masses/,/^2 2/d' \
    'psys: bad.data: no Masses section (atom_style atomic needs a mass for each atom type)'
bad '/^Pair Coeffs/,/^2 1 1/d' \
    'psys: bad.data: no Pair Coeffs section (written by write_data ... nocoeff, or before pair_coeff): give --epsilon and --sigma'
bad 's/^-5 5 xlo xhi/-1 1 xlo xhi/' \
    'psys: bad.data: pair force 0: the cutoff (2.5) must be less than half the periodic box (box length 2 on axis 0) (use a smaller --cutoff or a larger box)'
bad 's/^2 atoms/2 atomz/' \
    'psys: bad.data: line 3: unknown header line (got "2 atomz")'
bad 's/^2 atoms/0 atoms/' \
    'psys: bad.data: line 3: no atoms: nothing to import (got "0 atoms")'
bad '/zlo zhi/d' \
    'psys: bad.data: the header has no "zlo zhi" line (psys needs the box)'
bad '/^Atoms/,$d' \
    'psys: bad.data: no Atoms section'

: >empty.data
sentinel out.json
psys import lammps empty.data --out out.json
expect_rc 2 "empty file"
expect_stderr 'psys: empty.data: empty file (a LAMMPS data file starts with a title line, then its header)' "empty file"
expect_untouched out.json "empty file"

# Bad usage.
usage() { # EXPECTED-STDERR ARGS...
    local want=$1
    shift
    psys import "$@"
    expect_rc 2 "import $*"
    expect_stderr "$want" "import $*"
}
usage 'psys: import: unknown format (got gromacs; known: lammps)' gromacs good.data --out x.json
cp good.data good.data.orig
usage 'psys: ./good.data: --out would replace the data file it reads' lammps good.data --out ./good.data
check "import --out naming its input leaves it" cmp -s good.data good.data.orig
usage 'psys: import: no --out file given (usage: psys import lammps FILE.data --out SCENE.json [options]; see psys --help)' lammps good.data
usage 'psys: import: give --epsilon and --sigma together' lammps good.data --out x.json --epsilon 1
usage 'psys: --cutoff: must be a finite number > 0 (got -1)' lammps good.data --out x.json --cutoff -1
usage 'psys: --steps: must be an integer from 0 to 1e15 (got 1.5)' lammps good.data --out x.json --steps 1.5
usage 'psys: import: unknown option --bogus (see psys --help)' lammps good.data --out x.json --bogus
usage 'psys: missing.data: cannot open: No such file or directory' lammps missing.data --out x.json
usage 'psys: --out /nonexistent/dir/x.json: cannot create: No such file or directory' lammps good.data --out /nonexistent/dir/x.json
expect_absent x.json "no output after bad usage"

# psys --help documents the command.
psys --help
expect_eq 1 "$(grep -c '^  psys import lammps FILE.data --out SCENE.json' out.txt)" "--help lists psys import"

finish
