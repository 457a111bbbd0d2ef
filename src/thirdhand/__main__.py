"""``python -m thirdhand`` runs the command line."""

from thirdhand.cli import main

raise SystemExit(main())
