from globe.cli.main import main

main()
