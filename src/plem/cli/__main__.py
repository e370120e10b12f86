"""`python -m plem.cli`: the `plem` command without its console script."""

from plem.cli.app import main

main()
