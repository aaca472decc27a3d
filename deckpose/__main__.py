import sys

from deckpose.cli import main

sys.exit(main())
