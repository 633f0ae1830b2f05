# The compiled build's C types for the board's wire module (setup.py): the index of check_ints is a C integer

cimport cython

@cython.locals(i=cython.Py_ssize_t)
cpdef check_ints(values, specs, topic, field=*)
