#!/usr/bin/env python3
"""Open truepos QIF exports in a second, independent QIF reader: the `xmlschema` package
(PyPI) builds the QIF 3.0 schema set itself, validates each file (keys and keyrefs included)
and decodes it into Python objects; the script prints the decoded feature measurement and
characteristics so they can be compared with `truepos fit --json`.

Never run in CI. Usage (from the repository root; a throw-away venv):

    python3 -m venv /tmp/qifvenv && /tmp/qifvenv/bin/pip install xmlschema
    /tmp/qifvenv/bin/python scripts/qif_second_reader.py data/schemas/qif3 FILE.qif ...
"""
import sys
import xmlschema

def main():
    schema_dir, files = sys.argv[1], sys.argv[2:]
    schema = xmlschema.XMLSchema(f"{schema_dir}/QIFApplications/QIFDocument.xsd")
    bad = 0
    for f in files:
        errors = list(schema.iter_errors(f))
        if errors:
            bad += 1
            print(f"{f}: INVALID ({len(errors)} errors): {errors[0].reason}")
            continue
        doc = schema.to_dict(f)
        units = doc["FileUnits"]["PrimaryUnits"]["LinearUnit"]["UnitName"]
        res = doc["Results"]["MeasurementResultsSet"]["MeasurementResults"]
        res = res[0] if isinstance(res, list) else res
        feats = {k: v for k, v in res["MeasuredFeatures"].items() if k.endswith("FeatureMeasurement")}
        print(f"{f}: valid; linear unit {units}")
        for k, v in feats.items():
            for m in (v if isinstance(v, list) else [v]):
                keep = {kk: vv for kk, vv in m.items() if kk in
                        ("Location", "Normal", "Direction", "Axis", "Diameter", "FullAngle", "Form")}
                print(f"  {k}: {keep}")
        chars = res.get("MeasuredCharacteristics", {}).get("CharacteristicMeasurements", {})
        for k, v in chars.items():
            if k.endswith("CharacteristicMeasurement"):
                for m in (v if isinstance(v, list) else [v]):
                    print(f"  {k}: status {m['Status']['CharacteristicStatusEnum']}, value {m.get('Value')}")
        print(f"  InspectionStatus: {res['InspectionStatus']['InspectionStatusEnum']}")
    sys.exit(1 if bad else 0)

if __name__ == "__main__":
    main()
