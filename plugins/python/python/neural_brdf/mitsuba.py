"""The neural and measured BRDFs as a Mitsuba 3 BSDF plugin, ``"neural_brdf"``.

.. code-block:: python

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")          # or scalar_rgb, cuda_ad_rgb, ...
    import neural_brdf.mitsuba
    neural_brdf.mitsuba.register()
    bsdf = mi.load_dict({"type": "neural_brdf",
                         "filename": "scenes/materials/latent.bin",
                         "material": "alum-bronze"})

Parameters:

- ``filename`` (string): a latent file (``latent.bin``; then ``material`` names the code to
  decode) or a MERL table (``.binary``). Relative paths go through Mitsuba's file resolver.
- ``material`` (string): the latent code's name (latent files only).

Spatially varying forms (the renderer's glTF ``{"neural": {"mix": ...}}`` and
``{"neural": {"blend": ...}}``, docs/plugins.md), with Mitsuba textures evaluated at each
shading point (``si.uv``); ``filename`` is then a latent file and ``material`` is not given:

- ``mix`` (string): 1 to 4 codes of the latent file, comma-separated, e.g.
  ``"dark-red-paint, aluminium"``; ``weights`` (texture, e.g. a ``bitmap`` with ``raw: true``):
  its R, G, B values are the weights of the first three codes; ``weights_alpha`` (texture or
  float, default 1 = the renderer's alpha of a texture without one) the fourth code's. Per
  point, exactly the renderer's mixture: weights that are not positive and finite count as 0,
  the rest are normalised to sum 1, all 0 gives the first code alone; f = Σ w_k f_k,
  pdf = Σ w_k pdf_k, sampling chooses a code by weight (as renderer::bsdf::Mixture).
  Every code is evaluated for every point and weighted.
- ``blend`` (string): two codes ``"A, B"``; ``t`` (texture or float in [0, 1]; NaN counts as
  0, values outside are clamped as in the renderer) and ``channel`` (0, 1 or 2, default 0: the
  texture channel holding t). As the renderer: a palette of 32 decodes of the latent
  interpolation z(t_k), t_k = k / 31 (``Material.blend_palette``), and at t the mixture of
  entries k = min(floor(31 t), 30) and k + 1 with weights (1 − a, a), a = 31 t − k. The two
  neighbours are evaluated per point by Dr.Jit calls (``drjit.switch`` on the entry index),
  so each point runs two of the 32 networks.

The BSDF is a one-sided glossy reflection (``GlossyReflection | FrontSide``), exactly the
renderer's: the same decoded target net, the same f_ref (trilinear over measured bins) and
mapping for a latent code, the same trilinear look-up for a table, and the same tabulated
importance sampler with its exact density, so ``eval``/``pdf``/``sample``/``eval_pdf``
agree with ``neural_brdf.Material`` and with ``render``, and MIS with emitter sampling works
as for Mitsuba's own BSDFs.

- In the JIT variants (``llvm_*``, ``cuda_*``) everything is written in Dr.Jit operations and
  traced into Mitsuba's kernels over the whole wavefront: the MLP as cooperative-vector
  matrix products (``drjit.nn.matvec``) over the decoded weights packed in one buffer,
  f_ref (or the table) and the sampler's tables as Dr.Jit arrays read with gathers. Nothing
  calls back into Python per sample.
- In the scalar variants each call goes to the package's native code (one direction pair).

Mitsuba's ``si.wi`` (toward the viewer) is the renderer's ``wo`` and Mitsuba's ``wo``
(toward the light) the renderer's ``wi``; Mitsuba's ``eval`` includes the cosine
foreshortening cos θ of the light direction, the renderer's f_r does not.
"""

import math

import numpy as np

from ._native import MAX_LOG_VALUE, MAX_MIX_PARTS, Material

__all__ = ["register", "PLUGIN_NAME"]

PLUGIN_NAME = "neural_brdf"

# The renderer's constants (renderer::formats::merl, renderer::brdf_coords).
THETA_H_BINS, THETA_D_BINS, PHI_D_BINS = 90, 90, 180
MAX_RENDER_VALUE = 1e30
PHI_H_GUARD = 1e-7
ONE_MINUS_EPSILON = float(np.nextafter(np.float32(1.0), np.float32(0.0)))


def register(name=PLUGIN_NAME):
    """Registers the BSDF plugin ``name`` for the Mitsuba variant set now (call
    ``mi.set_variant`` first; register again after switching variants)."""
    import mitsuba as mi

    if not mi.variant():
        raise RuntimeError("neural_brdf.mitsuba.register(): call mitsuba.set_variant(...) first")
    cls = _bsdf_class()
    mi.register_bsdf(name, lambda props: cls(props))


def _bsdf_class():
    """The BSDF class for the current variant (its base class depends on the variant)."""
    import drjit as dr
    import mitsuba as mi

    class NeuralBrdf(mi.BSDF):
        def __init__(self, props):
            super().__init__(props)
            filename = str(props.get("filename", ""))
            if not filename:
                raise ValueError("neural_brdf: the 'filename' parameter is required")
            resolver = mi.file_resolver() if hasattr(mi, "file_resolver") else mi.Thread.thread().file_resolver()
            filename = str(resolver.resolve(filename))
            name = str(props.get("material", "")) or None
            mix, blend = str(props.get("mix", "")), str(props.get("blend", ""))
            self.jit = dr.is_jit_v(mi.Float)
            self.form = "mix" if mix else "blend" if blend else "one"
            if mix and blend or (mix or blend) and name:
                raise ValueError(f"neural_brdf: give one of 'material', 'mix' and 'blend' ({filename})")
            if self.form == "one":
                self.material = Material.open(filename, name)
                if self.material.kind not in ("neural", "merl"):
                    raise ValueError(f"{filename}: neural_brdf takes a latent file or a MERL table (.binary), not a {self.material.kind} network")
                self.parts = [self.material]
            elif self.form == "mix":
                codes = _codes(mix, "mix", 1, MAX_MIX_PARTS)
                if "weights" not in props:
                    raise ValueError(f"neural_brdf: 'mix' needs a 'weights' texture ({filename})")
                self.parts = [Material.open(filename, code) for code in codes]
                self.weights = props.get("weights")
                self.weights_alpha = props.get("weights_alpha", 1.0)
                self.material = Material.mix(self.parts, [1.0] * len(self.parts))
            else:
                a, b = _codes(blend, "blend", 2, 2)
                if "t" not in props:
                    raise ValueError(f"neural_brdf: 'blend' needs 't' (a texture or a float) ({filename})")
                self.t = props.get("t")
                self.channel = int(props.get("channel", 0))
                if self.channel not in (0, 1, 2):
                    raise ValueError(f"neural_brdf: 'channel' is {self.channel}, not 0, 1 or 2 ({filename})")
                self.parts = Material.blend_palette(filename, a, b)
                self.material = self.parts[0]
            self.m_flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]
            if self.jit:
                bins = {}
                self.kernels = [_JitMaterial(m, bins) for m in self.parts]
                self.kernel = self.kernels[0]

        # ---- the mixture at a point ----------------------------------------------------

        def _mixture(self, si, active, normalise=True):
            """(entries, weights) of the point's mixture: entries the kernels' indices (ints,
            or UInt32 per point for a blend), weights normalised as renderer::bsdf::Mixture
            (or as they come, with `normalise` false)."""
            if self.form == "mix":
                rgb = self.weights.eval(si, active)
                raw = [rgb[0], rgb[1], rgb[2]][: len(self.parts)]
                if len(self.parts) == 4:
                    alpha = self.weights_alpha
                    raw.append(alpha.eval_1(si, active) if hasattr(alpha, "eval_1") else mi.Float(float(alpha)))
                return list(range(len(self.parts))), (_normalised(raw) if normalise else raw)
            if hasattr(self.t, "eval"):
                t = self.t.eval(si, active)[self.channel]
            else:
                t = mi.Float(float(self.t))
            last = len(self.parts) - 1
            t = dr.select(dr.isnan(t), 0.0, t)
            s = dr.clip(t, 0.0, 1.0) * float(last)
            k = dr.minimum(mi.UInt32(s), last - 1)
            a = s - mi.Float(k)
            return [k, k + 1], (_normalised([1.0 - a, a]) if normalise else [1.0 - a, a])

        def _call(self, entry, method, *args):
            """kernels[entry].method(*args): a direct call, or per point by Dr.Jit's switch."""
            if isinstance(entry, int):
                return getattr(self.kernels[entry], method)(*args)
            return dr.switch(entry, [getattr(k, method) for k in self.kernels], *args)

        def _value_pdf(self, si, wo_r, wi_r, active, value=True, pdf=True):
            """The mixture's f_r (no cosine) and pdf at the point, in the renderer's directions."""
            if self.form == "one":
                return (self.kernel.value(wo_r, wi_r) if value else None), (self.kernel.pdf(wo_r, wi_r) if pdf else None)
            entries, weights = self._mixture(si, active)
            f, p = mi.Color3f(0.0), mi.Float(0.0)
            for e, w in zip(entries, weights):
                if value:
                    f += w * self._call(e, "value", wo_r, wi_r)
                if pdf:
                    p += w * self._call(e, "pdf", wo_r, wi_r)
            return (f if value else None), (p if pdf else None)

        def _scalar_material(self, si):
            """The scalar variants' native material at the point (a mixture made per call)."""
            if self.form == "one":
                return self.material
            entries, weights = self._mixture(si, True, normalise=False)
            # As renderer::bsdf::Mixture::new: unusable weights count as 0, all 0 is the first.
            weights = [float(w) if float(w) > 0.0 and math.isfinite(float(w)) else 0.0 for w in weights]
            keep = [(self.parts[int(e)], w) for e, w in zip(entries, weights) if w > 0.0]
            if not keep or not math.isfinite(sum(weights)):
                return self.parts[int(entries[0])]
            if len(keep) == 1:
                return keep[0][0]
            return Material.mix([m for m, _ in keep], [w for _, w in keep])

        # Mitsuba's si.wi is the renderer's wo; Mitsuba's wo is the renderer's wi.

        def eval(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0)
            if self.jit:
                f, _ = self._value_pdf(si, si.wi, wo, active, pdf=False)
                return dr.select(active, f * dr.maximum(wo.z, 0.0), 0.0)
            f = self._scalar_material(si).eval(_row(si.wi), _row(wo))[0]
            return mi.Color3f(*(float(c) * max(wo.z, 0.0) for c in f)) if active else mi.Color3f(0.0)

        def pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Float(0.0)
            if self.jit:
                _, pdf = self._value_pdf(si, si.wi, wo, active, value=False)
                return dr.select(active, pdf, 0.0)
            return mi.Float(float(self._scalar_material(si).pdf(_row(si.wi), _row(wo))[0])) if active else mi.Float(0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0), mi.Float(0.0)
            if self.jit:
                f, pdf = self._value_pdf(si, si.wi, wo, active)
                return dr.select(active, f * dr.maximum(wo.z, 0.0), 0.0), dr.select(active, pdf, 0.0)
            f, pdf = self._scalar_material(si).eval_pdf(_row(si.wi), _row(wo))
            if not active:
                return mi.Color3f(0.0), mi.Float(0.0)
            return mi.Color3f(*(float(c) * max(wo.z, 0.0) for c in f[0])), mi.Float(float(pdf[0]))

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = dr.zeros(mi.BSDFSample3f)
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return bs, mi.Color3f(0.0)
            if self.jit:
                if self.form == "one":
                    wi, valid = self.kernel.sample(si.wi, sample1, sample2)
                else:
                    entries, weights = self._mixture(si, active)
                    entry, uc = _choose(entries, weights, sample1)
                    wi, valid = self._call(entry, "sample", si.wi, uc, sample2)
                f, pdf = self._value_pdf(si, si.wi, wi, active)
                valid &= active & (pdf > 0.0) & dr.isfinite(pdf)
                weight = dr.select(valid, f * wi.z / pdf, 0.0)
            else:
                u = np.array([[sample2[0], sample2[1], sample1]], dtype=np.float32)
                wi_n, f_n, pdf_n = self._scalar_material(si).sample(_row(si.wi), u)
                pdf = mi.Float(float(pdf_n[0]))
                wi = mi.Vector3f(*(float(c) for c in wi_n[0]))
                valid = bool(active) and pdf > 0.0
                weight = mi.Color3f(*(float(c) * wi.z / pdf for c in f_n[0])) if valid else mi.Color3f(0.0)
            bs.wo = wi
            bs.pdf = dr.select(valid, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            return bs, weight

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            if self.form == "blend":
                return f"NeuralBrdf[blend '{self.parts[0].name}' .. '{self.parts[-1].name}', {len(self.parts)} entries]"
            return f"NeuralBrdf[{self.material.kind} '{self.material.name}']"

    return NeuralBrdf


def _codes(text, form, fewest, most):
    """The comma-separated code names of a `mix` or `blend` parameter."""
    codes = [c.strip() for c in text.split(",") if c.strip()]
    if not fewest <= len(codes) <= most:
        wanted = f"{fewest}" if fewest == most else f"{fewest} to {most}"
        raise ValueError(f"neural_brdf: '{form}' names {len(codes)} codes ({text!r}), not {wanted}")
    return codes


def _normalised(raw):
    """Weights per point as renderer::bsdf::Mixture::new makes them: not positive and finite
    counts as 0, the rest divided by their sum; when none is left (or the sum overflows), the
    first part alone."""
    import drjit as dr

    usable = [dr.select((w > 0.0) & dr.isfinite(w), w, 0.0) for w in raw]
    total = usable[0]
    for w in usable[1:]:
        total = total + w
    ok = (total > 0.0) & dr.isfinite(total)
    safe = dr.select(ok, total, 1.0)
    return [dr.select(ok, w / safe, 1.0 if k == 0 else 0.0) for k, w in enumerate(usable)]


def _choose(entries, weights, uc):
    """The entry a mixture's sampling picks with the 1D sample `uc` and `uc` rescaled within
    its share, as renderer::bsdf::Mixture::sample (parts of weight 0 skipped; the last part
    of weight > 0 when uc falls past the others)."""
    import drjit as dr
    import mitsuba as mi

    n = len(weights)
    below, prefix = mi.Float(0.0), []
    for w in weights:
        prefix.append(below)
        below = below + w
    # The last part of weight > 0, and the sum below it.
    last_k, last_below, last_w = mi.UInt32(0), prefix[0], weights[0]
    for k in range(1, n):
        positive = weights[k] > 0.0
        last_k = dr.select(positive, k, last_k)
        last_below = dr.select(positive, prefix[k], last_below)
        last_w = dr.select(positive, weights[k], last_w)
    chosen, chosen_below, chosen_w = last_k, last_below, last_w
    found = mi.Bool(False)
    for k in range(n - 1):
        hit = ~found & (weights[k] > 0.0) & (uc < prefix[k] + weights[k]) & (mi.UInt32(k) < last_k)
        chosen = dr.select(hit, k, chosen)
        chosen_below = dr.select(hit, prefix[k], chosen_below)
        chosen_w = dr.select(hit, weights[k], chosen_w)
        found |= hit
    rest = dr.clip((uc - chosen_below) / chosen_w, 0.0, ONE_MINUS_EPSILON)
    entry = chosen if all(isinstance(e, int) and e == k for k, e in enumerate(entries)) else None
    if entry is None:
        # A blend: the entries are UInt32 per point.
        entry = entries[0]
        for k in range(1, n):
            entry = dr.select(chosen == k, entries[k], entry)
    return entry, rest


def _row(v):
    """A Mitsuba scalar vector as a (1, 3) array."""
    return np.array([[v[0], v[1], v[2]]], dtype=np.float32)


class _JitMaterial:
    """The renderer's BSDF in Dr.Jit operations: values (renderer::bsdf::neural and
    renderer::bsdf::merl) and the tabulated sampler (renderer::bsdf::tabulated_sampling),
    with the renderer's conventions (wo toward the viewer, wi toward the light)."""

    def __init__(self, material, shared=None):
        """`shared`: a dict in which the codes of one latent file share their f_ref buffer
        (the palette of a blend holds 32 codes)."""
        import mitsuba as mi

        self.neural = material.kind == "neural"
        if self.neural:
            values = None if shared is not None and "bins" in shared else material.f_ref.reshape(-1, 3)
            measured = None if values is None else np.all(values >= 0.0, axis=1)
            # Matrices (d_out × d_in) and biases packed into one buffer for drjit.nn.matvec.
            import drjit.nn as nn

            tensors = []
            for w, b in material.layers:
                tensors += [mi.TensorXf(np.ascontiguousarray(w.T)), mi.TensorXf(b)]
            packed = nn.pack(*tensors, layout="inference")
            self.layers = list(zip(packed[0::2], packed[1::2]))
            self.form, self.epsilon = material.mapping
        else:
            values = material.table.reshape(-1, 3)
            measured = np.ones(len(values), dtype=bool)
        if values is None:
            self.bins = shared["bins"]
        else:
            # (value·m, m) per bin, m = 1 where measured: the trilinear sum of the fourth channel
            # is the weight of the measured corners, by which the renderer renormalises.
            rgbm = np.zeros((len(values), 4), dtype=np.float32)
            rgbm[:, :3] = np.where(measured[:, None], values, 0.0)
            rgbm[:, 3] = measured
            self.bins = mi.Float(rgbm.ravel())
            if self.neural and shared is not None:
                shared["bins"] = self.bins

        t = material.sampler_tables()
        vals = t["values"].astype(np.float64)  # (nodes, lines, columns + 1)
        self.nodes, self.lines, self.line = vals.shape
        self.rows, self.columns = self.lines - 1, t["columns"]
        self.cosine_fraction = float(t["cosine_fraction"])
        row_v = t["row_v"].astype(np.float64)
        # As renderer::bsdf::tabulated_sampling::BilinearTable::new (values already scaled).
        dx = 1.0 / self.columns
        seg = 0.5 * (vals[:, :, :-1] + vals[:, :, 1:]) * dx
        line_cdf = np.concatenate([np.zeros(vals.shape[:2] + (1,)), np.cumsum(seg, axis=2)], axis=2)
        line_total = line_cdf[:, :, -1]
        masses = (row_v[1:] - row_v[:-1])[None, :] * 0.5 * (line_total[:, :-1] + line_total[:, 1:])
        total = masses.sum(axis=1)
        cdf = np.concatenate([np.zeros((self.nodes, 1)), np.cumsum(masses / self.rows, axis=1)], axis=1)
        cdf = cdf / np.where(cdf[:, -1:] > 0, cdf[:, -1:], 1.0)
        cdf[:, -1] = 1.0
        self.values = mi.Float(vals.astype(np.float32).ravel())
        self.line_cdf = mi.Float(line_cdf.astype(np.float32).ravel())
        self.row_cdf = mi.Float(cdf.astype(np.float32).ravel())
        self.total = mi.Float(total.astype(np.float32))
        self.row_v = mi.Float(row_v.astype(np.float32))

    # ---- values ------------------------------------------------------------------------

    def value(self, wo, wi):
        """f_r(wo, wi) in 1/sr (no cosine); zero below either horizon."""
        import drjit as dr
        import mitsuba as mi

        x, (theta_h, theta_d, phi_d) = _network_input_and_angles(wi, wo)
        rgbm = self._lookup(theta_h, theta_d, phi_d)
        table = mi.Color3f(rgbm.x, rgbm.y, rgbm.z)
        if self.neural:
            f_ref = dr.select(rgbm.w > 0.0, table / rgbm.w, 0.0)
            y = self._forward(x)
            scale = f_ref + self.epsilon
            e = dr.exp(dr.minimum(y, MAX_LOG_VALUE))
            f = (e if self.form == "talk" else e - 1.0) * scale - self.epsilon
            f = dr.clip(f, 0.0, MAX_RENDER_VALUE)
        else:
            f = table
        return dr.select((wo.z > 0.0) & (wi.z > 0.0), f, 0.0)

    def _forward(self, x):
        """The target net on the 6D input (list of Floats) -> y per channel (Color3f), as
        cooperative-vector matrix products over the packed weights."""
        import drjit as dr
        import drjit.nn as nn
        import mitsuba as mi

        h = nn.CoopVec(*x)
        last = len(self.layers) - 1
        for k, (w, b) in enumerate(self.layers):
            h = nn.matvec(w, h, b)
            if k < last:
                h = dr.maximum(h, 0.0)
        y = list(h)
        return mi.Color3f(y[0], y[1], y[2])

    def _lookup(self, theta_h, theta_d, phi_d):
        """Trilinear (value·m, m) over the bins, as renderer::formats::merl::trilinear_corners."""
        import drjit as dr
        import mitsuba as mi

        uh = dr.sqrt(dr.maximum(theta_h, 0.0) / (0.5 * math.pi)) * THETA_H_BINS - 0.5
        ud = theta_d / (0.5 * math.pi) * THETA_D_BINS - 0.5
        up = _fold_phi_d(phi_d) / math.pi * PHI_D_BINS - 0.5

        def clamp_axis(u, n):
            u = dr.clip(dr.select(dr.isnan(u), 0.0, u), 0.0, n - 1)
            i0 = dr.minimum(mi.UInt32(u), n - 1)
            return i0, dr.minimum(i0 + 1, n - 1), u - mi.Float(i0)

        h0, h1, fh = clamp_axis(uh, THETA_H_BINS)
        d0, d1, fd = clamp_axis(ud, THETA_D_BINS)
        up = dr.select(dr.isnan(up), 0.0, up)
        pf = dr.floor(up)
        fp = up - pf
        p0 = mi.UInt32((mi.Int32(pf) % PHI_D_BINS + PHI_D_BINS) % PHI_D_BINS)
        p1 = (p0 + 1) % PHI_D_BINS
        acc = mi.Vector4f(0.0)
        for ih, wh in ((h0, 1.0 - fh), (h1, fh)):
            for idd, wd in ((d0, 1.0 - fd), (d1, fd)):
                for ip, wp in ((p0, 1.0 - fp), (p1, fp)):
                    index = ip + PHI_D_BINS * (idd + THETA_D_BINS * ih)
                    acc += (wh * wd * wp) * dr.gather(mi.Vector4f, self.bins, index)
        return acc

    # ---- sampling ----------------------------------------------------------------------

    def _nodes(self, wo):
        import drjit as dr
        import mitsuba as mi

        s = _polar_angle(wo) / (0.5 * math.pi) * (self.nodes - 1)
        k = dr.minimum(mi.UInt32(dr.maximum(s, 0.0)), self.nodes - 2)
        return k, dr.clip(s - mi.Float(k), 0.0, 1.0)

    def _density(self, node, x, v, row):
        """A node's bilinear density per dx dv at (x, v) in row `row`."""
        import drjit as dr
        import mitsuba as mi

        v0 = dr.gather(mi.Float, self.row_v, row)
        v1 = dr.gather(mi.Float, self.row_v, row + 1)
        s = dr.clip((v - v0) / (v1 - v0), 0.0, 1.0)
        xc = dr.clip(x * self.columns, 0.0, self.columns)
        i = dr.minimum(mi.UInt32(xc), self.columns - 1)
        tau = xc - mi.Float(i)
        base = node * (self.lines * self.line) + row * self.line + i

        def at(offset):
            a = dr.gather(mi.Float, self.values, base + offset)
            b = dr.gather(mi.Float, self.values, base + offset + 1)
            return (1.0 - tau) * a + tau * b

        return ((1.0 - s) * at(0) + s * at(self.line)) / dr.gather(mi.Float, self.total, node)

    def pdf(self, wo, wi):
        """Solid-angle density of `sample` (1/sr); zero below either horizon."""
        import drjit as dr
        import mitsuba as mi

        cf = self.cosine_fraction
        h = dr.normalize(wo + wi)
        cos_oh = dr.dot(wo, h)
        c, s = _azimuth(wo)
        hx = c * h.x + s * h.y
        hy = -s * h.x + c * h.y
        theta_h = dr.atan2(dr.sqrt(hx * hx + hy * hy), h.z)
        row = dr.minimum(mi.UInt32(dr.sqrt(theta_h / (0.5 * math.pi)) * self.rows), self.rows - 1)
        half = dr.sin(0.5 * theta_h)
        v = 2.0 * half * half
        x = dr.minimum(dr.abs(dr.atan2(hy, hx)) / math.pi, 1.0)
        k, t = self._nodes(wo)
        density = (1.0 - t) * self._density(k, x, v, row) + t * self._density(k + 1, x, v, row)
        table = density / (2.0 * math.pi * 4.0 * cos_oh)
        table = dr.select((cos_oh > 0.0) & dr.isfinite(table), table, 0.0)
        pdf = cf * wi.z / math.pi + (1.0 - cf) * table
        return dr.select((wo.z > 0.0) & (wi.z > 0.0), pdf, 0.0)

    def sample(self, wo, uc, u):
        """(wi, valid) drawn given wo from a 1D sample `uc` (lobe, node, sign) and a 2D `u`."""
        import drjit as dr
        import mitsuba as mi

        cf = self.cosine_fraction
        cosine = (uc < cf) | (cf >= 1.0)
        wi_cosine = mi.warp.square_to_cosine_hemisphere(u)

        uc = (uc - cf) / max(1.0 - cf, 1e-30)
        k, t = self._nodes(wo)
        upper = uc >= 1.0 - t
        node = dr.select(upper, k + 1, k)
        uc = dr.select(upper, (uc - (1.0 - t)) / t, uc / (1.0 - t))
        sign = dr.select(uc < 0.5, 1.0, -1.0)

        rows, line = self.rows, self.line
        base_r = node * (rows + 1)
        r = dr.binary_search(0, rows - 1, lambda i: dr.gather(mi.Float, self.row_cdf, base_r + i + 1) <= u.y)
        c0 = dr.gather(mi.Float, self.row_cdf, base_r + r)
        c1 = dr.gather(mi.Float, self.row_cdf, base_r + r + 1)
        u_row = dr.select(c1 > c0, dr.clip((u.y - c0) / (c1 - c0), 0.0, ONE_MINUS_EPSILON), 0.5)
        line0 = node * (self.lines * line) + r * line
        line1 = line0 + line

        def cdf(i):
            return (1.0 - s) * dr.gather(mi.Float, self.line_cdf, line0 + i) + s * dr.gather(mi.Float, self.line_cdf, line1 + i)

        def vertex(i):
            return (1.0 - s) * dr.gather(mi.Float, self.values, line0 + i) + s * dr.gather(mi.Float, self.values, line1 + i)

        cols = self.columns
        s = _invert_linear(
            dr.gather(mi.Float, self.line_cdf, line0 + cols), dr.gather(mi.Float, self.line_cdf, line1 + cols), u_row
        )
        target = u.x * cdf(cols)
        lo = dr.binary_search(1, cols, lambda i: cdf(i) <= target) - 1
        qa, qb = vertex(lo), vertex(lo + 1)
        segment = 0.5 * (qa + qb) / cols
        fraction = dr.select(segment > 0.0, dr.clip((target - cdf(lo)) / segment, 0.0, 1.0), 0.5)
        x = (mi.Float(lo) + _invert_linear(qa, qb, fraction)) / cols
        v0 = dr.gather(mi.Float, self.row_v, r)
        v = v0 + s * (dr.gather(mi.Float, self.row_v, r + 1) - v0)

        sin_h = dr.sqrt(dr.maximum(v * (2.0 - v), 0.0))
        sp, cp = dr.sincos(sign * x * math.pi)
        hlx, hly = sin_h * cp, sin_h * sp
        c, sn = _azimuth(wo)
        h = mi.Vector3f(c * hlx - sn * hly, sn * hlx + c * hly, 1.0 - v)
        cos_oh = dr.dot(wo, h)
        wi_table = 2.0 * cos_oh * h - wo
        valid_table = (wi_table.z > 0.0) & (cos_oh > 0.0)

        wi = dr.select(cosine, wi_cosine, dr.normalize(wi_table))
        valid = dr.select(cosine, wi_cosine.z > 0.0, valid_table) & (wo.z > 0.0)
        return wi, valid


def _invert_linear(a, b, u):
    """s in [0, 1] where the integral of (1 − t) a + t b over [0, s] is the fraction u of its
    integral over [0, 1] (renderer::bsdf::tabulated_sampling::invert_linear)."""
    import drjit as dr

    c = u * 0.5 * (a + b)
    denominator = a + dr.sqrt(dr.maximum(a * a + 2.0 * (b - a) * c, 0.0))
    return dr.select(denominator > 0.0, dr.clip(2.0 * c / denominator, 0.0, 1.0), u)


def _azimuth(v):
    """cos and sin of the azimuth of v (1 and 0 along z)."""
    import drjit as dr

    s = dr.sqrt(v.x * v.x + v.y * v.y)
    ok = s > 1e-7
    return dr.select(ok, v.x / s, 1.0), dr.select(ok, v.y / s, 0.0)


def _polar_angle(v):
    import drjit as dr

    return dr.atan2(dr.sqrt(v.x * v.x + v.y * v.y), v.z)


def _fold_phi_d(phi):
    """phi_d folded into [0, π) (renderer::brdf_coords::fold_phi_d)."""
    import drjit as dr

    r = phi - math.pi * dr.trunc(phi / math.pi)  # fmod
    r = dr.select(r < 0.0, r + math.pi, r)
    return dr.select(r >= math.pi, r - math.pi, r)


def _network_input_and_angles(wi, wo):
    """The 6D network input and (θh, θd, φd) of (wi, wo), φd
    folded into [0, π) (renderer::brdf_coords::network_input_and_angles)."""
    import drjit as dr
    import mitsuba as mi

    s = wi + wo
    len2 = dr.squared_norm(s)
    h = dr.select(len2 > 1e-20, s * dr.rsqrt(len2), mi.Vector3f(0.0, 0.0, 1.0))
    sin_h = dr.sqrt(h.x * h.x + h.y * h.y)
    guard = sin_h > PHI_H_GUARD
    cp = dr.select(guard, h.x / sin_h, 1.0)
    sp = dr.select(guard, h.y / sin_h, 0.0)
    x1 = cp * wi.x + sp * wi.y
    y1 = -sp * wi.x + cp * wi.y
    ct, st = h.z, sin_h
    d = mi.Vector3f(ct * x1 - st * wi.z, y1, st * x1 + ct * wi.z)
    fold = (d.y < 0.0) | ((d.y == 0.0) & (d.x < 0.0))
    d = mi.Vector3f(dr.select(fold, -d.x, d.x), dr.select(fold, -d.y, d.y), d.z)
    angles = (dr.atan2(sin_h, h.z), _polar_angle(d), _fold_phi_d(dr.atan2(d.y, d.x)))
    return [sin_h, dr.zeros(mi.Float, dr.width(sin_h)), h.z, d.x, d.y, d.z], angles
