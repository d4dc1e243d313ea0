"""``python -m roar_formal.cli``: the same as ``roar-verify``."""

from . import main

main()
