"""The `lubrig` command line."""
