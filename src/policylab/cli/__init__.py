"""The ``policylab`` command line."""
