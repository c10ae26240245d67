"""Assembly machinery any discretization can use: batched element matrices and fixed sparsity patterns.

==================  ====================================================
module              what it holds
==================  ====================================================
``batched``         element matrices of a bilinear form through its kernel
``pattern``         a CSR pattern fixed at setup, filled every step
==================  ====================================================
"""
