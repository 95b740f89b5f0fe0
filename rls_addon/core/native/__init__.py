"""The compiled library (one shared library of C kernels), its loader, ABI checks and thread policy, with the numpy helpers that sum as the kernels sum."""
