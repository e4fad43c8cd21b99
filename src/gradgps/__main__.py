"""``python -m gradgps`` runs the command line."""

from gradgps._cli import main

if __name__ == "__main__":
    main()
