"""refType names: PTB's DCC good-practice vocabulary (`basic_*`) and our own (`ratebench_*`).

A refType tells a machine reader what a DCC element means without parsing its human name.
Where the good-practice vocabulary has a term we use it; quantities it has no term for
get a `ratebench_` term, defined in docs/dcc.md. The terms every DCC uses are here; a
procedure kind defines its quantities' terms in its DCC part (`procedures/*/dcc.py`, as
`RB + "name"`). Both namespaces are declared in the DCC's refTypeDefinitions, as the DCC
schema asks, so a reader knows where each term is defined.
"""

from __future__ import annotations

from dataclasses import dataclass

# PTB DCC good practice, namespace "basic"
NOMINAL = "basic_nominalValue"
MEASURED = "basic_measuredValue"
ERROR = "basic_measurementError"
REFERENCE = "basic_referenceValue"
CONFORMITY = "basic_conformity"
LIMIT_LOW = "basic_acceptanceLimitLower"
LIMIT_HIGH = "basic_acceptanceLimitUpper"
METHOD = "basic_calibrationMethod"
UNCERTAINTY = "basic_uncertainty"
NORMAL_USED = "basic_normalUsed"
TEMPERATURE = "basic_temperature"
TEMPERATURE_MIN, TEMPERATURE_MAX = "basic_temperatureMin", "basic_temperatureMax"
HUMIDITY = "basic_humidityRelative"
HUMIDITY_MIN, HUMIDITY_MAX = "basic_humidityRelativeMin", "basic_humidityRelativeMax"

# ours, namespace "ratebench" (docs/dcc.md, section "refTypes"); a kind's own: RB + "name"
RB = "ratebench_"
BUDGET = RB + "uncertaintyBudget"
STANDARD_UNCERTAINTY = RB + "standardUncertainty"
RAW_DIGESTS = RB + "rawDataDigests"
SHA256 = RB + "sha256"
SIMULATED = RB + "simulatedStand"
LOCATION = RB + "itemLocation"
COUNTRY_UNKNOWN = RB + "countryNotConfigured"
CONDITION = RB + "condition"
RUN_DIRECTORY = RB + "runDirectory"
DRAFT = RB + "draftNotAuthorised"
AUTHORISATION = RB + "authorisation"
EQUIPMENT = RB + "equipmentStatus"    # the lab register's inventory on the run's date
EQUIPMENT_IDENTITY = RB + "equipmentIdentity"   # an item without an identity of its own
# the traceability table's columns, on each measuringEquipment (docs/dcc.md)
SERIAL_NUMBER = RB + "serialNumber"
CALIBRATION_CERTIFICATE = RB + "calibrationCertificate"
CALIBRATION_ISSUER = RB + "calibrationIssuer"
CALIBRATION_DUE = RB + "calibrationDue"
QUANTITY_TRACED = RB + "quantityTraced"
TRACEABILITY_STATUS = RB + "traceabilityStatus"
REPORTED_IDENTITY = RB + "reportedIdentity"
SENSITIVITY = RB + "sensitivityCoefficient"
#: the item as received and as left, the decision rule's agreement (ISO/IEC 17025 7.8.2.1 g,
#: 7.8.4.1 b, 7.1.3); a setting that differs from its read-back; the lab's accreditation
ITEM_STATE = RB + "itemState"
READBACK = RB + "settingReadBack"
ACCREDITATION = RB + "accreditation"
#: r of two correlated inputs of a budget (GUM 5.2.2)
CORRELATION = RB + "correlationCoefficient"
TOLERANCE_LOW = RB + "toleranceLimitLower"      # the maker's specification, not acceptance
TOLERANCE_HIGH = RB + "toleranceLimitUpper"


@dataclass(frozen=True)
class Namespace:
    name: str
    prefix: str
    link: str
    description: str


BASIC = Namespace(
    "DCC good practice: basic refTypes", "basic",
    "https://digilab.ptb.de/dkd/refType/vocab/index.php?tema=2",
    "The 'basic' namespace of PTB's refType vocabulary: terms common to all measurands "
    "(nominal value, measured value, measurement error, conformity, acceptance limits, ...).")
RATEBENCH = Namespace(
    "ratebench refTypes", "ratebench", "urn:x-ratebench:dcc:reftypes:1",
    "Terms of the ratebench rate-table bench for quantities the basic vocabulary does not "
    "name (per-turn rate error and instability, intra-turn instability, FOG cross-calibration, "
    "gyro drift, azimuth, raw-data digests); each is defined in the project's docs/dcc.md, "
    "section refTypes, with the docs/method.md section it comes from.")
NAMESPACES = (BASIC, RATEBENCH)
