"""Allow ``python -m dyadbench``."""

from dyadbench.cli import main

if __name__ == "__main__":
    main()
