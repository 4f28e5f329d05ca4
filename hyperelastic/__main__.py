"""`python -m hyperelastic ...` is the `hyperelastic` command."""
from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
