# The board runs this file at boot. It stays source (the board compiles it), so it is kept to two lines: the
# firmware itself, train.py and what it imports, is precompiled to .mpy (cbtc flash) and costs no compile heap.
import train

train.main()
