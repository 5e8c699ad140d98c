"""bbzide.vm room: a byte-faithful Python model of the BittyBuzz VM (see ARCHITECTURE.md).

The model is this folder, readable top to bottom: :mod:`bbzide.vm.vm` (the VM record and
its instructions), :mod:`bbzide.vm.heap`, :mod:`bbzide.vm.gc`, :mod:`bbzide.vm.tables`, the
runtime libraries and :class:`bbzide.vm.robot.Robot` (the firmware loop the worlds drive).
Its compiled kernels are in ``compiled/``, reached only through :mod:`bbzide.vm.kernels`.
Nothing is imported here.
"""
