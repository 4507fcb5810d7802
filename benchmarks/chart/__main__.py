from tiltpile.bench.chart import main

raise SystemExit(main())
