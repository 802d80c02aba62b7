"""``python -m aeromag``: the same command line as ``aeromag``."""

from .cli import main

if __name__ == "__main__":
    main()
