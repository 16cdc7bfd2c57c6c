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

from ._native import MAX_LOG_VALUE, Material

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
            self.material = Material.open(filename, name)
            if self.material.kind not in ("neural", "merl"):
                raise ValueError(f"{filename}: neural_brdf takes a latent file or a MERL table (.binary), not a {self.material.kind} network")
            self.m_flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]
            self.jit = dr.is_jit_v(mi.Float)
            if self.jit:
                self.kernel = _JitMaterial(self.material)

        # Mitsuba's si.wi is the renderer's wo; Mitsuba's wo is the renderer's wi.

        def eval(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0)
            if self.jit:
                f = self.kernel.value(si.wi, wo)
                return dr.select(active, f * dr.maximum(wo.z, 0.0), 0.0)
            f = self.material.eval(_row(si.wi), _row(wo))[0]
            return mi.Color3f(*(float(c) * max(wo.z, 0.0) for c in f)) if active else mi.Color3f(0.0)

        def pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Float(0.0)
            if self.jit:
                return dr.select(active, self.kernel.pdf(si.wi, wo), 0.0)
            return mi.Float(float(self.material.pdf(_row(si.wi), _row(wo))[0])) if active else mi.Float(0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return mi.Color3f(0.0), mi.Float(0.0)
            if self.jit:
                f = self.kernel.value(si.wi, wo)
                pdf = self.kernel.pdf(si.wi, wo)
                return dr.select(active, f * dr.maximum(wo.z, 0.0), 0.0), dr.select(active, pdf, 0.0)
            f, pdf = self.material.eval_pdf(_row(si.wi), _row(wo))
            if not active:
                return mi.Color3f(0.0), mi.Float(0.0)
            return mi.Color3f(*(float(c) * max(wo.z, 0.0) for c in f[0])), mi.Float(float(pdf[0]))

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = dr.zeros(mi.BSDFSample3f)
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection):
                return bs, mi.Color3f(0.0)
            if self.jit:
                wi, valid = self.kernel.sample(si.wi, sample1, sample2)
                f = self.kernel.value(si.wi, wi)
                pdf = self.kernel.pdf(si.wi, wi)
                valid &= active & (pdf > 0.0) & dr.isfinite(pdf)
                weight = dr.select(valid, f * wi.z / pdf, 0.0)
            else:
                u = np.array([[sample2[0], sample2[1], sample1]], dtype=np.float32)
                wi_n, f_n, pdf_n = self.material.sample(_row(si.wi), u)
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
            return f"NeuralBrdf[{self.material.kind} '{self.material.name}']"

    return NeuralBrdf


def _row(v):
    """A Mitsuba scalar vector as a (1, 3) array."""
    return np.array([[v[0], v[1], v[2]]], dtype=np.float32)


class _JitMaterial:
    """The renderer's BSDF in Dr.Jit operations: values (renderer::bsdf::neural and
    renderer::bsdf::merl) and the tabulated sampler (renderer::bsdf::tabulated_sampling),
    with the renderer's conventions (wo toward the viewer, wi toward the light)."""

    def __init__(self, material):
        import mitsuba as mi

        self.neural = material.kind == "neural"
        if self.neural:
            values = material.f_ref.reshape(-1, 3)
            measured = np.all(values >= 0.0, axis=1)
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
        # (value·m, m) per bin, m = 1 where measured: the trilinear sum of the fourth channel is
        # the weight of the measured corners, by which the renderer renormalises.
        rgbm = np.zeros((len(values), 4), dtype=np.float32)
        rgbm[:, :3] = np.where(measured[:, None], values, 0.0)
        rgbm[:, 3] = measured
        self.bins = mi.Float(rgbm.ravel())

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
