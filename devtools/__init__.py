"""Development tools, run from the checkout and never installed: the benchmark (``make bench``),
its replans and SITL flights, the ArduCopter and PX4 software-in-the-loop launchers that the
benchmark and the flight tests use, and the generator of docs/node.md's parameter tables
(``make docs``). They import the package; the package never imports them.
"""
