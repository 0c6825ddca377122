from ._laparo import __version__
