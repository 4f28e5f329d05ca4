"""Reproduction of the thesis experiments (issue 3): scripts/repro_*.py call these modules."""
