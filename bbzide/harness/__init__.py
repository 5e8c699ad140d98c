"""The corpus harness: one robot on the VM model, driven by the command line of the
conformance corpus (``bbzide run X.bzz --platform P --reg NAME=KIND --inject FILE ...``), whose
``#BBZDUMP`` output is compared byte for byte with the reference firmware's.

A tool on top of the VM room: it imports the model, the model never imports it.
"""
