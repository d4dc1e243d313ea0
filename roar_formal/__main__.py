"""``python -m roar_formal``: the same as ``roar-verify``."""

from .cli import main

main()
