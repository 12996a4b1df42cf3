from surgopt.cli import main

main()
