from benchmarks.chart import main

raise SystemExit(main())
