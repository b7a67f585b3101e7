"""Reference answers of notebook 03's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 03.K` to the next, is what the student cell of
exercise 03.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 03 --solutions` put it in.
"""

# exercise 03.1
def height_loss_lab(p_a, p_b_hat, r_a, r_b_hat, h_a, h_b, lambda_g=5.0):
    """Height loss L_h of Kim et al. 2020 (Eq. 17), each smoothL1 a mean over its elements.

    Args:
        p_a: (B, T, J, 3) source root-relative joint positions (torch).
        p_b_hat: (B, T, J, 3) output root-relative joint positions.
        r_a: (B, T, 3) source root positions.
        r_b_hat: (B, T, 3) output root positions.
        h_a, h_b: the source's and the target's heights H, metres (floats).
        lambda_g: weight of the root term.

    Returns:
        () the loss, a torch scalar.
    """

    def mean_smooth_l1(x):  # Eq. 14, averaged over every element
        size = x.abs()
        return torch.where(size < 1.0, 0.5 * x * x, size - 0.5).mean()

    l_a = (p_a[:, 1:] - p_a[:, :-1]).norm(dim=-1) / h_a  # (B, T-1, J): Eqs. 9 and 11
    l_b = (p_b_hat[:, 1:] - p_b_hat[:, :-1]).norm(dim=-1) / h_b  # Eqs. 10 and 12
    m_a = r_a[:, 1:].norm(dim=-1) / h_a  # (B, T-1): Eq. 15, frames 2..T
    m_b = r_b_hat[:, 1:].norm(dim=-1) / h_b  # Eq. 16
    return mean_smooth_l1(l_a - l_b) + lambda_g * mean_smooth_l1(m_a - m_b)

# exercise 03.2
# the leg ratio is smaller than the height ratio here, so copy's m_B runs below the source's m_A (the
# height-loss section); the root term lengthens the whole root vector r_B, its height included,
# until |r_B| / H_B matches |r_A| / H_A: the hips rise (and the jumps grow). Without it (lambda_g = 0)
# nothing moves the root.
hips_move = "up"  # the root term lifts the hips with the whole root vector

# exercise 03.3
excess = np.radians(angles - 100.0)  # E(q) - alpha for every joint and frame, radians
literal_lt = float(np.mean(excess**2))

# exercise 03.4
lr_power = -4  # (1 - 1.01)**2 = 1e-4: a one percent error in the norm costs its square
