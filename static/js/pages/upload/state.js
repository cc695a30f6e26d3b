// Upload page state: the form's vocabulary (derived from the service's OpenAPI schema) and the
// page's mutable state (chosen file, its preview, the tracks and vehicles to choose from).

// The vocabulary of this page comes from the service's OpenAPI schema, which is derived from
// the engine's CsvOptions (column roles, their units) and VehicleParams (Table 1 defaults).
export const GRAVITY_TEXT = {
  included: "Included (raw IMU, about +1 g at rest)",
  removed: "Removed (about 0 at rest)",
};

/** Column roles of the upload form: [{key, label, column, optional, unit, units, unitLabels}].
 * A role is optional when the schema says so (x-optional) or, for the chainage, when the
 * speed stands in for it. */
export function rolesOf(spec) {
  const props = spec.components.schemas.RunCreateJson.properties;
  const roles = [];
  for (const [name, p] of Object.entries(props)) {
    if (!name.endsWith("_column") || !p["x-role"]) continue;
    const key = p["x-role"];
    const unit = props[`${key}_unit`];
    const label = p["x-label"].charAt(0).toUpperCase() + p["x-label"].slice(1);
    const optional = key === "chainage" || Boolean(p["x-optional"]);
    roles.push({
      key, label: optional ? `${label} (optional)` : label, column: name, optional,
      unit: unit ? `${key}_unit` : null, units: unit ? unit["x-units"] : [],
      unitLabels: unit ? unit["x-unit-labels"] : {},
    });
  }
  return { roles, gravity: props.gravity["x-values"].filter((g) => g !== "auto") };
}

/** Vehicle parameters: [[name, label, unit, default]] (defaults: the Table 1 vehicle). The
 * numeric ones only: `kind` (the half car, the schema's default) is not typed in. */
export function vehicleFieldsOf(spec) {
  const props = spec.components.schemas.VehicleParamsSchema.properties;
  return Object.entries(props).filter(([, p]) => p.type === "number").map(([name, p]) => {
    const cut = p.description.lastIndexOf(", ");
    return [name, p.description.slice(0, cut), p.description.slice(cut + 2), p.default];
  });
}

/** The page's vocabulary from the OpenAPI schema: {roles, gravityModes, vehicleFields,
 * props} (props: the upload's fields with the bounds the service checks). */
export function vocabularyOf(spec) {
  const { roles, gravity } = rolesOf(spec);
  return {
    roles, gravityModes: gravity, vehicleFields: vehicleFieldsOf(spec),
    props: spec.components.schemas.RunCreateJson.properties,
    vehicleProps: spec.components.schemas.VehicleParamsSchema.properties,
  };
}

/** A fresh page state. `preview` is {parsed, head, serverAuto, serverNow} once a file is read. */
export function createState(vocabulary) {
  return {
    ...vocabulary,
    stopped: false,
    pollTimer: null,
    previewTimer: null,
    file: null,
    preview: null,
    tracks: [],
    vehicles: [],
    gnssPlaced: false,
  };
}

/** A server preview as {mapping: role → {column, unit}, gravity}. */
export function fromServer(roles, s) {
  const mapping = {};
  for (const role of roles) {
    const col = s.mapping ? s.mapping[role.key] : null;
    if (col) mapping[role.key] = { column: col, unit: s.units ? s.units[role.key] || null : null };
  }
  return { mapping, gravity: s.gravity || null, source: "server" };
}

/** What "Automatic" would pick: the service's reading without options (the page never
 * recognises columns itself: the engine's reader is the one authority). */
export function currentRecognition(state) {
  const s = state.preview && state.preview.serverAuto;
  if (s && s.answer) return fromServer(state.roles, s.answer);
  return { mapping: {}, gravity: null, source: "none" };
}

/** How the file will be read with the current choices (for the column badges). */
export function effectiveReading(state) {
  const s = state.preview && state.preview.serverNow;
  if (s && s.answer) return fromServer(state.roles, s.answer);
  return currentRecognition(state);
}

export function roleOf(column, reading) {
  for (const [role, m] of Object.entries(reading.mapping)) if (m && m.column === column) return role;
  return null;
}

/**
 * Whether the run can be placed on the track without a start chainage: the file has a
 * chainage column, or GNSS fixes on a track with a centerline (state.gnssPlaced, kept by
 * gnss.js, issue 11). The form's "required" and its check follow this one predicate.
 */
export function canPlaceWithoutStart(state) {
  return Boolean(effectiveReading(state).mapping.chainage) || Boolean(state.gnssPlaced);
}

/** When the file says it was recorded (UTC ISO, from its epoch time column or a column of ISO
 * date-times), or null. */
export function fileRecordedAt(state) {
  const s = state.preview && state.preview.serverNow;
  return s && s.answer && s.answer.recorded_at ? s.answer.recorded_at : null;
}

/** A date as the value of a datetime-local input (the user's local time, minutes). */
export function localInputValue(date = new Date()) {
  const d = new Date(date);
  d.setSeconds(0, 0);
  const pad = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())}T${pad(d.getHours())}:${pad(d.getMinutes())}`;
}

export function formatBytes(n) {
  if (n < 1024) return `${n} B`;
  if (n < 1024 * 1024) return `${(n / 1024).toFixed(1)} KB`;
  return `${(n / 1024 / 1024).toFixed(1)} MB`;
}
