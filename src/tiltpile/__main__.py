from tiltpile.cli import main

raise SystemExit(main())
