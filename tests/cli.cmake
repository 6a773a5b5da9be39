# Command-line contract tests (docs/scene-format.md, docs/cli.md,
# docs/semantics.md): bash scripts in tests/cli/,
# each run as `bash tests/cli/NAME.sh PSYS SOURCE-ROOT` (see psys_cli_test).
psys_cli_test(bad_input)
psys_cli_test(csv_format)
psys_cli_test(roundtrip)
psys_cli_test(checkpoint)
psys_cli_test(nonfinite)
psys_cli_test(atomic)
psys_cli_test(subnormals)
