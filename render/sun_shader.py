"""The ``pbr`` shading's shaders: pyrender's lighting for one sun, at a fraction of its cost.

pyrender draws ``pbr`` materials with ``pyrender/shaders/mesh.frag``: loops over point,
spot and directional lights, each through Cook-Torrance, and a shadow test that reads
36 texels (nine bilinear 4-texel lookups). Under EGL/llvmpipe the fragment shader runs
on the CPU for every pixel: an 8 MP frame of the ship scene by day took 3.2 s against
0.9 s under ``flat`` (issue 23's budget for all realism: 1.5x).

The deck scene has one light, the sun (a directional light), plus ambient light, and
materials with a base colour (texture or vertex colours), metallic and roughness
factors. ``shaders/sun_lit.frag`` draws exactly that: the same Cook-Torrance terms
(Schlick's Fresnel, Smith-Schlick geometry, GGX distribution), the same ambient and
output encoding, and one bilinear 4-texel shadow lookup (the shadow's edge is one
shadow-map texel wide instead of three); ``shaders/sun_lit.vert`` hands it each vertex's
position in the shadow map's space. Point and spot lights, directional lights after the
first, normal, occlusion, emissive and metallic-roughness textures and glossy materials
are not drawn; the deck scene has none. With them (and one shadow pass
a frame, :mod:`deckpose.render.scene`) a whole ``pbr`` day frame of the ship look costs
1.40x (8 MP) to 1.44x (64 MP) a default one in wall time, 1.57x in CPU
(``reports/throughput/ship_cost.txt``); its raster about 2x a ``flat`` one.

:func:`sun_program_cache` is a pyrender ``ShaderProgramCache`` that loads these shaders
where pyrender asks for ``mesh.vert``/``mesh.frag`` and pyrender's own files for everything
else (the shadow pass's depth shaders, ``flat`` shading).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: The lean shaders, shipped with the package (``pyproject.toml``'s package data).
SUN_LIT_FRAG = Path(__file__).resolve().parent / "shaders" / "sun_lit.frag"
SUN_LIT_VERT = SUN_LIT_FRAG.with_suffix(".vert")


def sun_program_cache(pr: Any) -> Any:
    """A pyrender ``ShaderProgramCache`` that draws ``mesh.vert/.frag`` materials with ``sun_lit.vert/.frag``.

    Parameters
    ----------
    pr : module
        The imported ``pyrender`` (imported by the caller after choosing the GL platform).

    Returns
    -------
    pyrender.shader_program.ShaderProgramCache
        Its programs are keyed by file name, so they never mix with pyrender's own.
    """
    base = pr.shader_program.ShaderProgramCache

    class SunProgramCache(base):  # type: ignore[misc, valid-type]
        def get_program(self, vertex_shader: str, fragment_shader: str, geometry_shader: str | None = None,
                        defines: dict[str, Any] | None = None) -> Any:
            if fragment_shader == "mesh.frag":  # absolute paths: os.path.join keeps them as they are
                vertex_shader, fragment_shader = str(SUN_LIT_VERT), str(SUN_LIT_FRAG)
            return super().get_program(vertex_shader, fragment_shader, geometry_shader, defines)

    return SunProgramCache()
