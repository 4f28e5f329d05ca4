"""`python -m hyperelastic ...` is the `hyperelastic` command."""
from .cli.main import main

if __name__ == "__main__":
    raise SystemExit(main())
