# psys import lammps (apps/psys/cmd_import.c, lammps_data.c; docs/cli.md
# "psys import"): cli/lammps_import.sh checks the importer on hand-written
# data files (always runs); cli/lammps.sh runs LAMMPS (`lmp`) and psys on the
# same Lennard-Jones melt and compares kinetic and potential energy at steps
# 0, 50 and 100 to 1e-6 relative. It exits 77, reported as skipped, where lmp
# is not installed (scripts/install-deps.sh installs Debian's lammps).
psys_cli_test(lammps_import)
psys_cli_test(lammps)
set_tests_properties(cli.lammps PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 300)
