"""``python -m policylab`` runs the command line."""

from policylab.cli.main import main

main()
