"""Real spherical-harmonics constants of the 3DGS colour model, one source for every module.

A Gaussian's colour seen from direction d is 0.5 + Σ_lm c_lm Y_lm(d) with the real SH basis Y_lm of the
reference 3DGS implementation (Kerbl et al. 2023); its degree-0 value is the constant 1 / (2√π), so the
DC coefficient of a colour rgb is (rgb − 0.5) / SH_C0. File formats (.splat stores colour, not SH), the
procedural assets and the renderer all convert with these. A leaf module: no torch, no numpy.
"""

SH_C0 = 0.28209479177387814
"""Y_0^0 = 1 / (2√π): the degree-0 real SH basis value."""
SH_C1 = 0.4886025119029199
"""√3 / (2√π): the degree-1 basis factor."""
SH_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
"""The five degree-2 basis factors."""
SH_C3 = (
    -0.5900435899266435,
    2.890611442640554,
    -0.4570457994644658,
    0.3731763325901154,
    -0.4570457994644658,
    1.445305721320277,
    -0.5900435899266435,
)
"""The seven degree-3 basis factors."""
