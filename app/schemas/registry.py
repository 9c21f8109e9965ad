"""Each family's request schema, by the family's name: the one table the Python API and identify's
recommendation parse a family's request with (the routes name their schema in their signature)."""

from __future__ import annotations

from app.schemas.family import ProfileRequest
from app.schemas.pseudo_polynomial import PseudoPolynomialIn
from app.schemas.shapers import InputShapedRequest
from app.schemas.smoothers import SmootherRequest
from app.schemas.stap import StapIn
from app.schemas.time_optimal import TimeOptimalIn

REQUEST_SCHEMAS: dict[str, type[ProfileRequest]] = {  # in the order of app.family_names.NAMES (a test checks)
    "time_optimal": TimeOptimalIn,
    "pseudo_polynomial": PseudoPolynomialIn,
    "stap": StapIn,
    "smoother": SmootherRequest,
    "input_shaped": InputShapedRequest,
}
