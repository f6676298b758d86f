"""The applications on top: the CLI and its commands, the console, certificate rendering and
authorisation, the DCC writer, the records database and the station view.

Nothing below imports this package (the contract in pyproject.toml).
"""
