"""The scene model of the contact plug-in, one for 2D and 3D: [scene], [bodies], [contact],
[output] and [exact] (docs/scenes.md, "ContactScene"). The dimension is the bodies'
geometries' (`dimension.scene_dimension`, told before validation so that every table checks its
vectors, tensors and expressions against it); the 2D-only keys ([contact.electrical],
[output] potential_along) are refused in 3D with the field named."""

from __future__ import annotations

from functools import partial
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, model_validator

from fem.facets import ENDS
from problems.scene import SceneModel, Section
from problems.scene.exact import ExactSection
from problems.scene.fields import Text
from problems.scene.model import head, refuse

from . import electrical as electrical_contact
from . import law as contact_law
from . import model as contact_model
from .bodies import BodySection
from .dimension import ALIASES, scene_dimension
from .model import interface_references, reference

NAME = "contact"  # the plug-in; its former names (`dimension.ALIASES`) are still accepted
ONLY_2D = "absent in a 3D scene (electrical contact and potential plots are 2D only)"


class ContactSection(contact_law.ContactLaw):
    """[contact]: slave and master boundaries (BODY.BOUNDARY; master "rigid" for a rigid
    foundation along the slave boundary, or at the distance `gap` from it), the contact law
    (`contact_law.ContactLaw`, docs/coulomb.md "Contact laws of the plug-ins"; fields of x, y
    in 2D and x, y, z in 3D), the crosspoint basis and, in 2D, the electrical contact.

    law = "bilateral" (the paper's: the bodies stay in contact, λ_n of any sign) or
    "unilateral" (λ_n ≥ 0, gap ≥ 0, λ_n·gap = 0; two bodies may start apart, the gap is the
    geometry's); friction = "tresca" (bound g, a field ≥ 0 in Pa: the interval [−g, g] in 2D,
    the disc |λ_t| ≤ g in 3D; with law = "unilateral" it acts only where the bodies touch) or
    "coulomb" (bound F·λ_n, F a field ≥ 0; unilateral only); gap = the initial normal distance
    to a rigid foundation (m, a field ≥ 0; unilateral only); ends = the crosspoint basis,
    "merge" (default, Wohlmuth's end-node modification: a dropped node's dual functions go to
    its neighbours) or "keep" (they are dropped), `fem.facets.multiplier_basis`.
    """

    slave: Text
    master: Text = "rigid"
    ends: Literal[ENDS] = ENDS[0]
    electrical: electrical_contact.ElectricalSection | None = None


class OutputSection(Section):
    """[output]: potential_along = BODY.BOUNDARY (a plot of φ along it; 2D)."""

    potential_along: Text | None = None


Head = head(NAME, 1, *ALIASES)


class ContactScene(SceneModel):
    """A contact scene, 2D or 3D: bodies, an optional contact interface, output and exact
    solution; `dimension` is that of its geometries."""

    DIMENSION: ClassVar[int | None] = None  # told by the geometries (`dimension`)
    scene: Head
    bodies: Annotated[dict[str, BodySection], Field(min_length=1)]
    contact: ContactSection | None = None
    output: OutputSection | None = None
    exact: ExactSection | None = None  # read by `mixvi study` (`errors`)
    _dimension: int = PrivateAttr(2)

    @property
    def dimension(self) -> int:
        """2 or 3: the dimension of the scene's geometries."""
        return self._dimension

    @model_validator(mode="wrap")
    @classmethod
    def _by_dimension(cls, data: Any, handler: Any, info: ValidationInfo) -> Any:
        """Validate with the dimension in the context (told from the raw data if not given)."""
        context = info.context or {}
        if context.get("dimension") is not None:
            model = handler(data)
            model._dimension = context["dimension"]
            return model._references()
        dim = scene_dimension(data, context.get("file"))
        return cls.model_validate(data, context={**context, "dimension": dim})

    def _references(self) -> ContactScene:
        c = self.contact
        if c is not None:
            slave = interface_references(self.bodies, c)
            if c.electrical is not None:
                self._electrical(slave, c.electrical)
        along = None if self.output is None else self.output.potential_along
        if along is not None:
            field = ["output", "potential_along"]
            if self.dimension == 3:
                raise refuse(field, along, ONLY_2D)
            body, _ = reference(self.bodies, field, along)
            if not self.bodies[body].material.piezoelectric:
                raise refuse(field, along, "a boundary of a piezoelectric body")
        return self

    def _electrical(self, slave: str, e: electrical_contact.ElectricalSection) -> None:
        """Refuse [contact.electrical] in 3D, without a piezoelectric slave, and a foundation
        potential beside a piezoelectric master."""
        c, field = self.contact, ["contact", "electrical"]
        if self.dimension == 3:
            raise refuse(field, e.kind, ONLY_2D)
        if not self.bodies[slave].material.piezoelectric:
            raise refuse(field, e.kind, "only with a piezoelectric slave body")
        piezo_master = c.master != "rigid" and (
            self.bodies[c.master.split(".")[0]].material.piezoelectric
        )
        if piezo_master and e.kind != "insulating" and e.phi_F != 0.0:
            raise refuse(
                [*field, "phi_F"],
                e.phi_F,
                "0 (absent) with a piezoelectric master body: the charge flows into "
                "the master, whose potential takes the foundation's place",
            )


# the contract's `count` and `update` of both fronts (the dimension is the scene's)
count = partial(contact_model.count, ContactScene)
update = partial(contact_model.update_scene, ContactScene)
