from gyrocal.cli import entry

entry()
