"""bbzide.vm room: a byte-faithful Python model of the BittyBuzz VM (see ARCHITECTURE.md).

Entry points: :class:`bbzide.vm.vm.VM` (construct, set_bcode, step, closure calls),
:mod:`bbzide.vm.profiles` (platform configurations), :mod:`bbzide.vm.inspector`.
"""
