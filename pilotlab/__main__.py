from pilotlab.cli import main

if __name__ == "__main__":  # a guard: spawned worker processes import this module again
    raise SystemExit(main())
