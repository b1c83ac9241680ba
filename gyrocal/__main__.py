from gyrocal.cli import main

raise SystemExit(main())
