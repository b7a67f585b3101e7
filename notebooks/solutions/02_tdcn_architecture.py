"""Reference answers of notebook 02's exercises (docs/notebooks.md, "Writing an exercise").

Not a module: each block, from its line `# exercise 02.K` to the next, is what the student cell of
exercise 02.K holds once answered; it runs in the notebook after the cells above that cell. The
book never shows this file; `make book-teacher` and `retarget exercises 02 --solutions` put it in.
"""

# exercise 02.1
def dilated_conv(x, weight, dilation):
    """A valid 1-D convolution over time with dilated taps, no bias.

    Args:
        x: (B, C_in, T) input frames (torch).
        weight: (C_out, C_in, K) the kernel, as torch.nn.Conv1d stores it.
        dilation: d, the spacing of the taps in frames.

    Returns:
        (B, C_out, T - (K - 1) * dilation) output frames.
    """
    taps = weight.shape[-1]
    out_frames = x.shape[-1] - (taps - 1) * dilation
    y = 0
    for k in range(taps):  # tap k reads the input k * dilation frames after the output frame
        window = x[..., k * dilation : k * dilation + out_frames]  # (B, C_in, T_out)
        y = y + torch.einsum("oi,bit->bot", weight[..., k], window)
    return y

# exercise 02.2
# same: the input is edge-padded by as many frames as the receptive field needs (half of it at each
# end), so the generator gives one output frame per input frame whatever its dilations
output_frames_change = "same"

# exercise 02.3
a4_generator, a4_discriminator = build_model({"row": "A4", "profile": "fast"})
with torch.no_grad():
    a4_scores = a4_discriminator.eval()(d_in)  # (1, T_d - RF + 1): valid convolutions, no padding
a4_patches = a4_scores.shape[-1]

# exercise 02.4
frames_after_t = (gen.receptive_field - 1) // 2  # centred window: as many frames after t as before
lookahead_seconds = frames_after_t / clip.fps

# exercise 02.5
a1_generator = build_model({"row": "A1", "profile": "fast"}).generator
a1_last = a1_generator.body.blocks[-1].temporal.conv.weight.numel()  # 2d + 1 taps
dense_over_dilated = a1_last / gen.body.blocks[-1].temporal.conv.weight.numel()  # over 3 taps
