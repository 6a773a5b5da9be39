psys_cli_test(implicit)
