"""The report.html jinja2 template, kept as a module constant (no package-data files).

Every value is rendered through autoescape; nothing from the run is marked safe.
"""

REPORT_TEMPLATE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{% if r.run and (r.run.simulated or r.run.mode == "sim") %}SIMULATED — {% endif %}Calibration report — {{ r.unit_under_test.model }} {{ r.unit_under_test.serial }}</title>
<style>
body{font-family:sans-serif;max-width:60em;margin:1em auto;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:2px 6px;font-size:90%}
th{background:#eee}.pass{color:#070;font-weight:bold}.fail{color:#b00;font-weight:bold}
.simulated{border:3px dashed #a60;background:#fff4e0;color:#a60;padding:.5em 1em;margin:.5em 0}.warn{background:#fdd}.invalid{background:#b00;color:#fff;padding:.5em 1em;margin:.5em 0}code{font-size:85%}img{max-width:100%}
</style></head><body>
{% if r.run and (r.run.simulated or r.run.mode == "sim") %}<div class="simulated" id="simulated-banner"><b>SIMULATED — not a calibration.</b> This run drove simulated instruments (a dry run); no unit was calibrated and its numbers describe a simulation.</div>{% endif %}
<h1>{% if r.run and (r.run.simulated or r.run.mode == "sim") %}SIMULATED — {% endif %}Gyro calibration report</h1>
{% set overall = r.verdict.overall if r.verdict else ("PASS" if all_pass else "FAIL") %}
{% if overall == "INVALID" %}<div class="invalid"><b>INVALID</b> — the numbers are not physically possible, so no limit was judged:
<ul>{% for reason in r.verdict.invalid_because %}<li>{{ reason }}</li>{% endfor %}</ul></div>{% endif %}
<p><b>Overall: {% if overall == "PASS" %}<span class="pass">PASS</span>{% else %}<span class="fail">{{ overall }}</span>{% endif %}</b>
({{ r.acceptance|length }} acceptance limit(s){% if r.verdict %}; physics checks: {% for c in r.verdict.sanity %}{{ c.name }} {{ "ok" if c.ok else "FAILED" }}{% if not loop.last %}, {% endif %}{% endfor %}{% endif %})</p>

<h2>Unit, procedure, run</h2>
<table>
<tr><th>Unit under test</th><td>{{ r.unit_under_test.model }}, serial {{ r.unit_under_test.serial }}
 (output {{ r.unit_under_test.output_units }}, nominal SF {{ r.unit_under_test.nominal_scale_factor }})</td></tr>
<tr><th>Procedure</th><td>{{ r.procedure.name }} (<code>{{ r.procedure.file }}</code>)<br>{{ r.procedure.description }}</td></tr>
<tr><th>Station</th><td>{{ r.station.name }} (<code>{{ r.station.file }}</code>), site {{ r.station.site.name if r.station.site else "" }},
 latitude {{ r.station.site.latitude_deg if r.station.site else "unknown" }}°</td></tr>
<tr><th>Run</th><td>{{ r.run.run_id }} — mode {{ r.run.mode }}, seed {{ r.run.seed }}, speed {{ r.run.speed }}</td></tr>
<tr><th>Operator</th><td>{{ r.run.operator }}</td></tr>
<tr><th>Started / ended</th><td>{{ r.run.started_at }} / {% if r.run.ended_at %}{{ r.run.ended_at }}{% elif r.run.steps_done_at %}{{ r.run.steps_done_at }} (last step done; the run closed after this report was written){% else %}(not finished){% endif %}</td></tr>
<tr><th>Software</th><td>{{ r.run.software.name if r.run.software }} {{ r.run.software.version if r.run.software }}</td></tr>
<tr><th>Report built</th><td>{{ r.report_built_at }}</td></tr>
</table>

<h2>Instruments</h2>
<table><tr><th>Role</th><th>Make / model</th><th>Serial</th><th>Calibration certificate</th><th>Calibration due</th><th>Driver</th><th>Address</th><th>Identified as</th></tr>
{% for role, i in r.instruments.items() %}
<tr{% if i.calibration_overdue %} class="warn"{% endif %}><td>{{ role }}</td><td>{{ i.make or "" }} {{ i.model or "—" }}</td><td>{{ i.serial or "—" }}</td>
<td>{% if i.calibration_certificate or i.calibrated_by %}{{ i.calibration_certificate or "" }}{% if i.calibrated_by %} by {{ i.calibrated_by }}{% endif %}{% else %}—{% endif %}</td>
<td>{{ i.calibration_due or "—" }}{% if i.calibration_overdue %} <span class="fail">OVERDUE</span>{% endif %}</td>
<td>{{ i.driver or "—" }}</td><td><code>{{ i.address or "—" }}</code></td><td>{{ i.description or "—" }}</td></tr>
{% endfor %}</table>

<h2>Acceptance</h2>
<table><tr><th>Limit</th><th>Metric</th><th>Value ± U (95 %)</th><th>Limit</th><th>Decision rule (guard band)</th><th>Decision</th></tr>
{% for a in r.acceptance %}
<tr><td>{{ a.name }}</td><td><code>{{ a.metric }}</code></td>
{% set unit = unit_of(a) %}<td>{% if a.identifiable == false %}not identifiable (95 % upper bound {{ fmt(a.upper_bound_95) }} {{ unit }}){% elif a.value is none and a.why %}{{ a.why }}{% else %}{{ vu(a.value, a.U) }} {{ unit }}{% endif %}</td><td>{{ a.kind }} {{ fmt(a.limit) }} {{ unit }}</td>
<td>{{ a.decision_rule or "simple" }}{% if a.guard_band %} ({{ fmt(a.guard_band) }} {{ unit }}){% endif %}</td>
<td>{% set d = a.decision or ("PASS" if a["pass"] else "FAIL") %}<span class="{{ 'pass' if d == 'PASS' else 'fail' }}">{{ d }}</span></td></tr>
{% else %}<tr><td colspan="6">no acceptance limits in the procedure</td></tr>{% endfor %}
</table>

<h2>Scale factor</h2>
<p>Each value ± its expanded uncertainty U (≈ 95 %, coverage factor k; budgets in results.json), printed to the digits U supports.</p>
<table><tr><th>Temp (°C)</th><th>Sensor (°C)</th><th>SF (LS) ± U ({{ r.unit_under_test.output_units }} per deg/s)</th><th>k</th><th>SF+</th><th>SF−</th><th>Asymmetry ± U (ppm)</th><th>Nonlin. RMS ± U (%)</th><th>Nonlin. max ± U (ppm FS)</th></tr>
{% for e in r.scale_factor %}{% set un = e.uncertainty or {} %}
<tr><td>{{ fmt(e.temp_c) }}</td><td>{{ fmt(e.sensor_temp_c) }}</td><td>{{ vu(e.sf, e.U) }}</td><td>{{ fmt(e.k, 3) }}</td><td>{{ vu(e.sf_plus, e.U) }}</td><td>{{ vu(e.sf_minus, e.U) }}</td>
<td>{{ vu(e.asymmetry_ppm, un.asymmetry_ppm and un.asymmetry_ppm.U) }}</td><td>{{ vu(e.nonlinearity.rms_pct, un.nonlinearity_rms_pct and un.nonlinearity_rms_pct.U) }}</td><td>{{ vu(e.nonlinearity.max_ppm_fs, un.nonlinearity_max_ppm_fs and un.nonlinearity_max_ppm_fs.U) }}</td></tr>
{% endfor %}</table>
{% set un = r.uncertainty or {} %}
<p>LS line at the reference: {% if r.scale_factor_ls %}SF {{ vu(r.scale_factor_ls.sf, r.scale_factor_ls.U) }}, bias {{ vu(r.scale_factor_ls.bias, un["scale_factor_ls.bias"] and un["scale_factor_ls.bias"].U) }} at {{ fmt(r.scale_factor_ls.temp_c) }} °C{% else %}not computed{% endif %}.
Worst nonlinearity: {% if r.nonlinearity %}{{ vu(r.nonlinearity.rms_pct, un["nonlinearity.rms_pct"] and un["nonlinearity.rms_pct"].U) }} % RMS, {{ vu(r.nonlinearity.max_ppm_fs, un["nonlinearity.max_ppm_fs"] and un["nonlinearity.max_ppm_fs"].U) }} ppm FS{% else %}not computed{% endif %}.
Asymmetry: {{ vu(r.asymmetry_ppm, un["asymmetry_ppm"] and un["asymmetry_ppm"].U) }} ppm.
SF over temperature: {% if r.sf_temperature %}instability {{ vu(r.sf_temperature.instability_pct, un["sf_temperature.instability_pct"] and un["sf_temperature.instability_pct"].U) }} %, sensitivity {{ vu(r.sf_temperature.sensitivity_ppm_per_c, un["sf_temperature.sensitivity_ppm_per_c"] and un["sf_temperature.sensitivity_ppm_per_c"].U) }} ppm/°C{% else %}not computed{% endif %}.
(Values ± U, ≈ 95 %.)</p>
{% for key in ["sf_vs_rate", "nonlinearity", "sf_vs_temp"] %}{% if plots[key] %}<img alt="{{ key }}" src="data:image/png;base64,{{ plots[key] }}">{% endif %}{% endfor %}

<h2>Bias</h2>
<p>Earth rate removed: {{ fmt(r.earth_rate_removed_dph) }} deg/h (vertical input axis at the station latitude).</p>
<table><tr><th>Temp (°C)</th><th>Bias ± U (deg/h)</th><th>k</th><th>From</th></tr>
{% for b in r.bias %}<tr><td>{{ fmt(b.temp_c) }}</td><td>{{ vu(b.bias_dph, b.U) }}</td><td>{{ fmt(b.k, 3) }}</td><td>{{ b.source }}</td></tr>{% endfor %}</table>
<p>Bias temperature sensitivity: {% if r.bias_temperature %}{{ vu(r.bias_temperature.sensitivity_dph_per_c, r.bias_temperature.U) }} deg/h/°C{% else %}not computed{% endif %}.</p>
{% if plots.bias_vs_temp %}<img alt="bias vs temperature" src="data:image/png;base64,{{ plots.bias_vs_temp }}">{% endif %}

<h2>Allan deviation and noise terms</h2>
{% if r.allan %}
<p>Hold {{ r.allan.step_id }} at {{ fmt(r.allan.temp_c) }} °C, {{ fmt(r.allan.duration_s) }} s at {{ fmt(r.allan.rate_hz) }} Hz; {{ r.allan.method }}.</p>
<table><tr><th>Term</th><th>Value ± U (95 %)</th><th>k</th><th>68 % interval</th></tr>
{% for name, label, unit in terms %}{% set au = (r.allan.uncertainty or {})[name] %}<tr><td>{{ label }}</td><td>{% if (r.allan.identifiable or {})[name] == false %}not identifiable from this record (95 % upper bound {{ fmt(r.allan.upper_bound_95[name]) }} {{ unit }}){% else %}{{ vu(r.allan.fit[name], au and au.U) }} {{ unit }}{% endif %}</td><td>{{ fmt(au and au.k, 3) if au else "—" }}</td>
<td>{% set u = r.allan.fit_uncertainty[name] %}{{ fmt(u.lo) }} … {{ fmt(u.hi) }} {{ unit }}</td></tr>{% endfor %}
<tr><td>Markov (correlated bias: σ, T<sub>c</sub>)</td><td colspan="3">{% if r.allan.fit.markov %}{{ fmt(r.allan.fit.markov.sigma_dph) }} deg/h, {{ fmt(r.allan.fit.markov.tau_s) }} s{% else %}not significant{% endif %}</td></tr>
</table>
{% if plots.allan %}<img alt="Allan deviation" src="data:image/png;base64,{{ plots.allan }}">{% endif %}
{% else %}<p>Not computed.</p>{% endif %}

{% if r.threshold %}
<h2>Threshold and resolution (IEEE Std 952 / IEEE Std 1431)</h2>
<p>Rate increments alternated with the base rate; an increment counts when its output change (against the base dwells either side) is resolved at the stated one-sided confidence and lies within the stated fraction of the commanded change, and every larger increment does too. U is the increment grid's (rectangular between the largest failing and the smallest passing increment, k = {{ fmt(r.threshold.k) }}).
Threshold: {{ vu(r.threshold.threshold_dps, un["threshold.threshold_dps"] and un["threshold.threshold_dps"].U) }} deg/s; resolution: {{ vu(r.threshold.resolution_dps, un["threshold.resolution_dps"] and un["threshold.resolution_dps"].U) }} deg/s.</p>
<table><tr><th>Test</th><th>°C</th><th>Base (deg/s)</th><th>Confidence / fraction</th><th>Increments: commanded → measured ± u (deg/s)</th><th>Result (deg/s)</th></tr>
{% for t in r.threshold.tests %}<tr><td>{{ t.standard_test }}</td><td>{{ fmt(t.temp_c) }}</td><td>{{ fmt(t.base_rate_dps) }}</td><td>{{ fmt(t.confidence) }} / {{ fmt(t.max_error_fraction) }}</td>
<td>{% for i in t.increments %}{{ fmt(i.commanded_dps) }} → {{ fmt(i.measured_dps, 3) }} ± {{ fmt(i.u_dps, 2) }} {{ "✓" if i.passes else "✗" }}{% if not loop.last %}; {% endif %}{% endfor %}</td>
<td>{% if t.threshold_dps is not none %}{{ fmt(t.threshold_dps) }} (in ({{ fmt(t.below_dps) }}, {{ fmt(t.threshold_dps) }}]){% else %}above {{ fmt(t.below_dps) }}{% endif %}</td></tr>
{% endfor %}</table>
{% endif %}

{% if r.rate_limits %}
<h2>Input rate limits (IEEE Std 952 / IEEE Std 1431)</h2>
<p>Rates walked up to the declared maximum each way; a rate follows when its output lies within the stated % of the line fitted through the lowest rates. The maximum input rate is the largest rate that follows with every smaller one; U is the walk's grid (rectangular up to the first rate that does not follow, k = {{ fmt(r.rate_limits.k) }}).
Positive: {{ vu(r.rate_limits.max_positive_dps, un["rate_limits.max_positive_dps"] and un["rate_limits.max_positive_dps"].U) }} deg/s; negative: {{ vu(r.rate_limits.max_negative_dps, un["rate_limits.max_negative_dps"] and un["rate_limits.max_negative_dps"].U) }} deg/s.</p>
<table><tr><th>°C</th><th>Direction</th><th>Tolerance (%)</th><th>Rate (deg/s): deviation from the fit (%)</th><th>Maximum (deg/s)</th></tr>
{% for t in r.rate_limits.tests %}<tr><td>{{ fmt(t.temp_c) }}</td><td>{{ t.direction }}</td><td>{{ fmt(t.linearity_tolerance_pct) }}</td>
<td>{% for p in t.points %}{{ fmt(p.rate_dps) }}: {{ fmt(p.deviation_pct, 3) }} {{ "✓" if p.follows else "✗" }}{% if not loop.last %}; {% endif %}{% endfor %}</td>
<td>{% if t.max_dps is not none %}{{ fmt(t.max_dps) }}{% if t.next_dps is not none %} (limit in [{{ fmt(t.max_dps) }}, {{ fmt(t.next_dps) }})){% else %} (not reached){% endif %}{% else %}—{% endif %}</td></tr>
{% endfor %}</table>
{% endif %}

{% if r.frequency_response %}
<h2>Frequency response (IEEE Std 952 / IEEE Std 1431)</h2>
<p>The table turned a sinusoid in synthesis mode at each frequency; sines fitted to the gyro output and to the table rate give the gain (over the nominal scale factor) and the phase. The −3 dB bandwidth is the first crossing, between the linear and logarithmic interpolations, with the fits' type A and a rectangular interpolation term; the phase's u adds a one-sample timing term (k = {{ fmt(r.frequency_response.k) }}).
Bandwidth: {{ vu(r.frequency_response.bandwidth_hz, un["frequency_response.bandwidth_hz"] and un["frequency_response.bandwidth_hz"].U) }} Hz; phase at {{ fmt(r.frequency_response.tests[0].phase_at_hz) }} Hz: {{ vu(r.frequency_response.phase_deg, un["frequency_response.phase_deg"] and un["frequency_response.phase_deg"].U) }}°.</p>
<table><tr><th>°C</th><th>Hz</th><th>Gain (dB) ± u</th><th>Phase (°) ± u</th></tr>
{% for t in r.frequency_response.tests %}{% for p in t.points %}<tr><td>{{ fmt(t.temp_c) }}</td><td>{{ fmt(p.freq_hz) }}</td><td>{{ fmt(p.gain_db, 4) }} ± {{ fmt(p.u_gain_db, 2) }}</td><td>{{ fmt(p.phase_deg, 4) }} ± {{ fmt(p.u_phase_deg, 2) }}</td></tr>
{% endfor %}{% endfor %}</table>
{% endif %}

{% if r.turn_on %}
<h2>Turn-on time and warm-up (IEEE Std 952 / IEEE Std 1431)</h2>
<p>The station's supply switched the unit off, then on, the table at rest; the gyro was polled from the output-on command and logged from its first valid frame. The turn-on time is the middle of the poll interval the first frame came in (rectangular u); b∞ + A·e^(−t/τ) is fitted to 1-s means from the output-on (type A u), and the time until the bias stays within ±{{ fmt(r.turn_on.band_dph) }} deg/h of b∞ follows from the fit (k = {{ fmt(r.turn_on.k) }}).
Turn-on time: {{ vu(r.turn_on.time_to_first_data_s, un["turn_on.time_to_first_data_s"] and un["turn_on.time_to_first_data_s"].U) }} s; τ: {{ vu(r.turn_on.warmup_tau_s, un["turn_on.warmup_tau_s"] and un["turn_on.warmup_tau_s"].U) }} s; A: {{ vu(r.turn_on.warmup_amplitude_dph, un["turn_on.warmup_amplitude_dph"] and un["turn_on.warmup_amplitude_dph"].U) }} deg/h; time to the band: {{ vu(r.turn_on.time_to_band_s, un["turn_on.time_to_band_s"] and un["turn_on.time_to_band_s"].U) }} s.</p>
<table><tr><th>Step</th><th>°C</th><th>First data (s)</th><th>τ (s) ± u</th><th>A (deg/h) ± u</th><th>b∞ (deg/h)</th><th>Band (s), fit ± u</th><th>Band (s), measured</th></tr>
{% for t in r.turn_on.tests %}<tr><td>{{ t.step_id }}</td><td>{{ fmt(t.temp_c) }}</td><td>{{ fmt(t.time_to_first_data_s, 4) }}</td><td>{{ fmt(t.warmup_tau_s, 4) }} ± {{ fmt(t.u_warmup_tau_s, 2) }}</td><td>{{ fmt(t.warmup_amplitude_dph, 4) }} ± {{ fmt(t.u_warmup_amplitude_dph, 2) }}</td><td>{{ fmt(t.settled_bias_dph, 4) }}</td><td>{{ fmt(t.time_to_band_s, 4) }} ± {{ fmt(t.u_time_to_band_s, 2) }}</td><td>{{ fmt(t.measured_time_to_band_s, 4) }}</td></tr>
{% endfor %}</table>
{% endif %}

{% if r.turn_on_repeatability %}
<h2>Turn-on-to-turn-on bias repeatability (IEEE Std 952 / IEEE Std 1431)</h2>
<p>The supply switched the unit off (cool-down) and on for each cycle; the bias of each is the mean of its record, logged after the settling time. The repeatability is their standard deviation, u = s/√(2(N−1)) (k = {{ fmt(r.turn_on_repeatability.k) }}); the in-run bias stability beside it is the pooled standard deviation of 1-s means within the records.
Repeatability: {{ vu(r.turn_on_repeatability.std_dph, un["turn_on_repeatability.std_dph"] and un["turn_on_repeatability.std_dph"].U) }} deg/h; in-run: {{ fmt(r.turn_on_repeatability.in_run_std_dph, 4) }} deg/h.</p>
<table><tr><th>Test</th><th>°C</th><th>N</th><th>Biases (deg/h)</th><th>s ± u (deg/h)</th><th>In-run (deg/h)</th></tr>
{% for t in r.turn_on_repeatability.tests %}<tr><td>{{ t.test }}</td><td>{{ fmt(t.temp_c) }}</td><td>{{ t.cycles }}</td><td>{% for b in t.biases_dph %}{{ fmt(b, 4) }} {% endfor %}</td><td>{{ fmt(t.std_dph, 4) }} ± {{ fmt(t.u_std_dph, 2) }}</td><td>{{ fmt(t.in_run_std_dph, 4) }}</td></tr>
{% endfor %}</table>
{% endif %}

<h2>Compensation tables</h2>
{% for what, t in r.compensation.tables.items() %}
{% set label, cunit = compensation[what] if what in compensation else (what, "") %}
<h3>{{ label }} ({{ cunit }})</h3>
{% for kind, table in t.items() %}{% if table %}
<p>{{ table.kind }}: in-sample RMS residual {{ fmt(table.residual_rms) }} {{ cunit }}, leave-one-out RMS {{ fmt(table.loo_residual_rms) }} {{ cunit }}, max {{ fmt(table.loo_residual_max) }} {{ cunit }}
{% if table.coefficients %}; coefficients (highest power first) {% for c in table.coefficients %}{{ fmt(c, 7) }}{% if not loop.last %}, {% endif %}{% endfor %}{% endif %}</p>
<table><tr><th>Temp (°C)</th><th>Value ± U (95 %, {{ cunit }})</th><th>k</th></tr>{% for p in table.points %}{% set tu = (table.uncertainty or [])[loop.index0] %}<tr><td>{{ fmt(p[0]) }}</td><td>{{ vu(p[1], tu and tu.U) }}</td><td>{{ fmt(tu and tu.k, 3) if tu else "—" }}</td></tr>{% endfor %}</table>
{% endif %}{% else %}{% endfor %}
{% endfor %}

{% if r.imu %}
<h2>Three-axis IMU calibration</h2>
<p>Mountings ({{ r.imu.mounting_order }}): {% for m in r.imu.mountings %}{{ m.name }} = IMU {{ m.up }} up{% if m.face %} (face {{ m.face }}){% endif %}{% if not loop.last %}; {% endif %}{% endfor %}.
Scale factor S<sub>ii</sub>; misalignment E<sub>ij</sub> = S<sub>ij</sub>/S<sub>ii</sub> (axis i senses E<sub>ij</sub> of the rate about j), µrad; bias S⁻¹·b with the vertical Earth rate removed. ± values are standard uncertainties (type A, least squares).</p>
{% for t in r.imu.temperatures %}
<h3>{{ fmt(t.temp_c) }} °C (setpoint {{ fmt(t.setpoint_c) }} °C; {{ t.dwells }} dwells, {{ t.dof }} dof per axis)</h3>
<table><tr><th>Axis</th><th>Scale factor</th><th>u (ppm)</th><th>E to x (µrad)</th><th>E to y (µrad)</th><th>E to z (µrad)</th><th>Bias (deg/h)</th><th>Nonlinearity RMS (%)</th><th>Asymmetry (ppm)</th></tr>
{% for a in ["x", "y", "z"] %}<tr><td>{{ a }}</td><td>{{ fmt(t.scale_factor[a], 9) }}</td><td>{{ fmt(t.u_scale_factor_ppm[a], 2) }}</td>
{% for b in ["x", "y", "z"] %}<td>{% if a == b %}—{% else %}{{ fmt(t.misalignment_urad[a ~ b], 5) }} ± {{ fmt(t.u_misalignment_urad[a ~ b], 2) }}{% endif %}</td>{% endfor %}
<td>{{ fmt(t.bias_dph[a]) }} ± {{ fmt(t.u_bias_dph[a], 2) }}</td><td>{{ fmt(t.axes[a].nonlinearity_rms_pct, 3) }}</td><td>{{ fmt(t.axes[a].asymmetry_ppm, 3) }}</td></tr>{% endfor %}
</table>
{% endfor %}
<h3>Check: residual body rate after compensation (RMS over the calibration dwells, deg/h)</h3>
<table><tr><th>Temp (°C)</th><th>x</th><th>y</th><th>z</th><th>leave-one-out x</th><th>y</th><th>z</th></tr>
{% for c in r.imu.check %}<tr><td>{{ fmt(c.temp_c) }}</td>
{% for a in ["x", "y", "z"] %}<td>{{ fmt(c.in_sample.rms_dph[a], 3) if c.in_sample else "n/a" }}</td>{% endfor %}
{% for a in ["x", "y", "z"] %}<td>{{ fmt(c.leave_one_out.rms_dph[a], 3) if c.leave_one_out else "n/a" }}</td>{% endfor %}</tr>{% endfor %}
</table>
<h3>Compensation tables over temperature (piecewise linear, the vendor's method)</h3>
<table><tr><th>Element</th>{% for t in r.imu.temperatures %}<th>{{ fmt(t.temp_c, 3) }} °C</th>{% endfor %}<th>leave-one-out RMS</th><th>polynomial LOO RMS</th></tr>
{% for name, c in r.imu.compensation.items() %}<tr><td>{{ name }}</td>{% for p in c.points %}<td>{{ fmt(p[1], 9) }}</td>{% endfor %}
<td>{{ fmt(c.tables.piecewise_linear.loo_residual_rms, 3) if c.tables else "n/a" }}</td>
<td>{{ fmt(c.tables[c.tables.keys()|reject("equalto", "piecewise_linear")|first].loo_residual_rms, 3) if c.tables else "n/a" }}</td></tr>{% endfor %}
</table>
{% set acc = r.imu.accelerometers %}{% if acc %}
<h3>Accelerometers from gravity (IEEE Std 1293 six-position method)</h3>
<p>Local gravity {{ fmt(acc.gravity.g, 9) }} g: {{ acc.gravity.source }}. Bias b<sub>i</sub> in mg; scale-factor error K<sub>ii</sub> − 1 in ppm (its u includes the gravity's {{ fmt(acc.gravity.u_rel_ppm, 2) }} ppm); misalignment M<sub>ij</sub> = K<sub>ij</sub>/K<sub>ii</sub> in µrad. ± values are standard uncertainties.</p>
{% for t in acc.temperatures %}
<h4>{{ fmt(t.temp_c) }} °C (setpoint {{ fmt(t.setpoint_c) }} °C; positions {{ t.positions|join(", ") }}; {{ t.dof }} dof per axis)</h4>
<table><tr><th>Accelerometer</th><th>Bias (mg)</th><th>SF error (ppm)</th><th>M to x (µrad)</th><th>M to y (µrad)</th><th>M to z (µrad)</th></tr>
{% for a in ["x", "y", "z"] %}<tr><td>{{ a }}</td><td>{{ fmt(t.bias_mg[a], 5) }} ± {{ fmt(t.u_bias_mg[a], 2) }}</td><td>{{ fmt(t.sf_error_ppm[a], 4) }} ± {{ fmt(t.u_sf_ppm[a], 2) }}</td>
{% for b in ["x", "y", "z"] %}<td>{% if a == b %}—{% else %}{{ fmt(t.misalignment_urad[a ~ b], 5) }} ± {{ fmt(t.u_misalignment_urad[a ~ b], 2) }}{% endif %}</td>{% endfor %}</tr>{% endfor %}
</table>
{% endfor %}
<p>Check: residual specific force after compensation (RMS over the six statics, µg) —
{% for c in acc.check %}{{ fmt(c.temp_c) }} °C: {% for a in ["x", "y", "z"] %}{{ a }} {{ fmt(c.in_sample.rms_ug[a], 3) if c.in_sample else "n/a" }} (leave-one-out {{ fmt(c.leave_one_out.rms_ug[a], 3) if c.leave_one_out else "n/a" }}){% if not loop.last %}, {% endif %}{% endfor %}{% if not loop.last %}; {% endif %}{% endfor %}.</p>
<table><tr><th>Element</th>{% for t in acc.temperatures %}<th>{{ fmt(t.temp_c, 3) }} °C</th>{% endfor %}<th>leave-one-out RMS</th><th>polynomial LOO RMS</th></tr>
{% for name, c in acc.compensation.items() %}<tr><td>{{ name }}</td>{% for p in c.points %}<td>{{ fmt(p[1], 6) }}</td>{% endfor %}
<td>{{ fmt(c.tables.piecewise_linear.loo_residual_rms, 3) if c.tables else "n/a" }}</td>
<td>{{ fmt(c.tables[c.tables.keys()|reject("equalto", "piecewise_linear")|first].loo_residual_rms, 3) if c.tables else "n/a" }}</td></tr>{% endfor %}
</table>
{% endif %}
{% endif %}

{% if r.table_interference %}
<h2>Table-induced interference (drive powered vs off)</h2>
{% for p in r.table_interference %}
<p>{{ p.powered_step }} (drive powered, at rest) against {{ p.off_step }} (drive off, interlock open), {{ fmt(p.setpoint_c) }} °C:
drift (standard deviation of {{ fmt(p.drift_tau_s) }} s means) {{ fmt(p.drift_powered_dph, 4) }} deg/h powered, {{ fmt(p.drift_off_dph, 4) }} deg/h off — ratio {{ fmt(p.drift_ratio, 3) }}.</p>
{% if p.lines %}<table><tr><th>Line (Hz)</th><th>Amplitude powered (deg/h, 0-to-peak)</th><th>Amplitude off (deg/h)</th><th>Harmonic of the lowest</th></tr>
{% for l in p.lines %}<tr><td>{{ fmt(l.frequency_hz, 6) }}</td><td>{{ fmt(l.amplitude_dph, 4) }}</td><td>{{ fmt(l.amplitude_off_dph, 3) }}</td><td>{{ l.harmonic if l.harmonic else "—" }}</td></tr>{% endfor %}
</table>{% else %}<p>No spectral line stands out of the powered record.</p>{% endif %}
{% endfor %}
{% endif %}

<h2>Run history (journal)</h2>
<p>{{ r.journal.event_count }} events; {{ r.journal.retries }} retries, {{ r.journal.faults }} faults, {{ r.journal.bad_steps }} bad (repeated) steps.</p>
<table><tr><th>#</th><th>Event</th><th>Details</th></tr>
{% for e in r.journal.events %}<tr><td>{{ e.seq }}</td><td>{{ e.event }}</td>
<td>{{ e.step_id or "" }} {{ describe(e) }}</td></tr>
{% else %}<tr><td colspan="3">no retries, faults or bad steps</td></tr>{% endfor %}</table>

<h2>Notes</h2>
<ul>{% for n in r.notes %}<li>{{ n }}</li>{% else %}<li>none</li>{% endfor %}</ul>

<h2>Hashes (SHA-256)</h2>
<table><tr><th>Input</th><th>Copy</th><th>SHA-256</th></tr>
{% for role, i in r.inputs.items() %}<tr><td>{{ role }}</td><td><code>{{ i['copy'] }}</code></td><td><code>{{ i['sha256'] }}</code></td></tr>{% endfor %}
<tr><td>plan record</td><td><code>plan.json</code></td><td><code>{{ r.run.plan_sha256 }}</code></td></tr>
<tr><td>samples ({{ r.journal.chunks }} chunks)</td><td>hash of the journal's chunk list</td><td><code>{{ r.journal.samples_sha256 }}</code></td></tr>
</table>
<p>Check every hash with <code>gyrocal verify RUN_DIR</code>.</p>
<h2>Signature</h2>
{% if r.signature and r.signature.signed %}<p>Signed with the station's Ed25519 key <code>{{ r.signature.key_fingerprint }}</code>.</p>
<table><tr><td>chain head signed</td><td><code>{{ r.signature.chain_head }}</code></td></tr>
<tr><td>numbers signed (SHA-256 of results.json without its signature)</td><td><code>{{ r.signature.results_sha256 }}</code></td></tr>
<tr><td>signature</td><td><code>{{ r.signature['signature'] }}</code></td></tr></table>
<p>Every controller session also ends the journal with a signature over its chain head. This page cannot vouch for itself: authenticity is shown only by <code>gyrocal verify RUN_DIR --key station.pub</code> with the public key from QA's own record, whose fingerprint must be the one above.</p>
{% elif r.signature and r.signature.key_fingerprint %}<p class="warn">Not signed: this report was rebuilt without the station's key <code>{{ r.signature.key_fingerprint }}</code>, which signed the run; <code>gyrocal verify</code> will fail it.</p>
{% else %}<p class="warn">Not signed: the station has no signing key (<code>gyrocal keys</code>), so <code>gyrocal verify</code> can show integrity only, not authenticity.</p>{% endif %}
</body></html>
"""
