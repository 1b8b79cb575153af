from pilotlab.cli import main

raise SystemExit(main())
