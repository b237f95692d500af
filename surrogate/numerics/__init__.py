"""Numerics the maps and the solver share: vectorised root finding for monotone functions of one
variable (:mod:`.roots`), by Chandrupatla's bracketing method (:mod:`.chandrupatla`).
"""
