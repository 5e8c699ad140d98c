"""The VM's compiled kernels (numba): the same routines as the model in ``bbzide/vm/``, as loops
over the heap bytes, the stack and the packed message rings, for the fast mode.

They depend on the model's constants and layouts, never the reverse: the model reaches them
only through its seam, :mod:`bbzide.vm.kernels`. Nothing is imported here, so importing one
kernel does not compile the others.
"""
