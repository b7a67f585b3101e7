"""Reference answers of notebook 07b's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 07b.K` to the next, is what the student cell of
exercise 07b.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 07b --solutions` put it in.
"""

# exercise 07b.1
def eso_step(energy, variables, adam, lr):
    """One ESO step (Eqs. 10-11 with Adam, App. B.1) on one frame.

    Args:
        energy: (h_enc, o_prev) -> E_full(t), a scalar tensor differentiable in both.
        variables: (h_enc (1, H), o_prev (1, 3)) the two variables, torch float32.
        adam: (first, second, steps): Adam's first moments (m_h, m_o) and second moments
            (v_h, v_o), shaped as the variables, and the steps taken so far n (0-d tensor).
        lr: the learning rate alpha (0-d tensor).

    Returns:
        ((h_enc, o_prev), (first, second, steps)) after the step: steps is n + 1.
    """
    beta1, beta2 = ADAM_BETAS
    leaves = [x.detach().requires_grad_(True) for x in variables]
    with torch.enable_grad():
        gradients = torch.autograd.grad(energy(*leaves), leaves)  # dE_full(t)/dh, dE_full(t)/do
    (m_h, m_o), (v_h, v_o), n = adam
    n = n + 1
    first = tuple(beta1 * m + (1 - beta1) * g for m, g in zip((m_h, m_o), gradients))
    second = tuple(beta2 * v + (1 - beta2) * g * g for v, g in zip((v_h, v_o), gradients))
    moved = tuple(
        x - lr * (m / (1 - beta1**n)) / ((v / (1 - beta2**n)).sqrt() + ADAM_EPS)
        for x, m, v in zip(variables, first, second)
    )
    return moved, (first, second, n)

# exercise 07b.2
closing_with_larger_beta = "down"  # the heavier E_int resists pulling the forearms into the belly

# exercise 07b.3
def relaxed_contact_lab(vertices, pairs, initial_vertices, blend):
    """ESO's relaxed self-contact term (App. B.1).

    Args:
        vertices: (V, 3) the current vertices (metres, torch).
        pairs: (K, 2) int vertex pairs (i, j) that should touch.
        initial_vertices: (V, 3) the network's initial output v0.
        blend: b, the fraction of the gap each end is pulled across (float in [0, 1]).

    Returns:
        () the mean over the 2K pair ends of |v_i - ((1 - b) v0_i + b v0_j)| (metres).
    """
    ends = torch.as_tensor(pairs, dtype=torch.long)
    v_i, v_j = vertices[ends[:, 0]], vertices[ends[:, 1]]
    start_i, start_j = initial_vertices[ends[:, 0]], initial_vertices[ends[:, 1]]
    goal_i = (1 - blend) * start_i + blend * start_j
    goal_j = (1 - blend) * start_j + blend * start_i
    return torch.cat([(v_i - goal_i).norm(dim=-1), (v_j - goal_j).norm(dim=-1)]).mean()
