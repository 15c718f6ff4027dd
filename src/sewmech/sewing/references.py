"""The published facts sewmech checks a machine against, and where each comes from.

Every check (:mod:`sewmech.sewing.checks`, :mod:`~sewmech.sewing.feed`,
:mod:`~sewmech.sewing.thread`), every value a shipped machine file takes from a publication, the
report and the interactive page cite a source by a short key in square brackets, such as
``[JB-dynamics]`` or ``[Juki-LK-1900B]``. :data:`REFERENCES` holds each key's entry: the full
bibliographic source, how far it was checked, and the facts sewmech takes from it (the value,
what it is, how it is used). ``docs/references.md`` is this list written out
(:func:`markdown`; ``python -m sewmech.sewing.references > docs/references.md`` writes it again,
and a test keeps the two the same).

A key is a word of letters and digits with at least one hyphen, starting with a capital
(:data:`KEY_PATTERN`), so that it cannot be mistaken for an index or a note such as
``[estimate]`` (the machine names of :data:`NOT_KEYS` excepted).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: a citation in text: a key in square brackets, not a Markdown link's text (no "(" after it)
KEY_PATTERN = re.compile(r"\[([A-Z][A-Za-z0-9]*(?:-[A-Za-z0-9]+)+)\](?!\()")

#: bracketed words of the key's form that are not citations: jb8-2.toml marks the values it
#: changed from jb1-3 with [JB8-2]
NOT_KEYS = frozenset({"JB8-2", "JB1-3"})

#: how far a source was checked, in words
CHECKED = {
    "seen": "the figure was seen in the source",
    "second-hand": "seen in a secondary document that names this source; not in the source itself",
    "title": "title and abstract only: the full text was not read, so no figure is taken from it",
    "copy": "read in full (a copy without its drawings and appendix tables)",
    "textbook": "standard textbook or standard knowledge; not checked against this edition",
}


@dataclass(frozen=True)
class Fact:
    """One published fact: its value, what it is, and how sewmech uses it."""

    value: str
    what: str
    used: str


@dataclass(frozen=True)
class Reference:
    """One source. ``background``: cited for a method or a formula, not for a value that a
    check or a machine file uses."""

    key: str
    source: str
    url: str
    checked: str
    facts: tuple[Fact, ...] = ()
    background: bool = False

    def brief(self) -> dict:
        """What a page needs to resolve the key: key, source, address."""
        return {"key": self.key, "source": self.source, "url": self.url}


def _r(key, source, url, checked, *facts, background=False) -> Reference:
    return Reference(key, source, url, checked, tuple(Fact(*f) for f in facts), background)


REFERENCES: tuple[Reference, ...] = (
    # ---- the research reports sewmech is built from ----------------------------------------
    _r("JB-kinematics",
       "《JB型缝纫机运动学研究报告》 (Research report on the kinematics of the JB sewing"
       " machine). Tongji University, Shanghai, machine theory and machine elements group"
       " (上海同济大学机械原理和机械零件研究组), and the JB theory group of the Shanghai Sewing"
       " Machine Research Institute (上海缝纫机研究所JB型缝纫机理论研究组). Research report, early"
       " 1980s (the project was set in 1980; the copy carries no date).",
       "", "copy",
       ("no feed at the regulator's 0 mark", "the stitch-length regulator's zero setting gives a"
        " stitch of zero (the feed fork only swings about its pin)",
        "check 'stitch at the regulator's zero mark' (|s| <= 0.01 mm); the zero mark of the"
        " shipped JB files"),
       ("the JB machine's mechanisms", "needle bar, link take-up, hook drive (crank, long rod,"
        " rocking shaft, slotted link, lower shaft) and the cam-driven feed with its regulator",
        "the topology of the shipped files jb1-3 and jb8-2 (their dimensions are estimates:"
        " the copy lacks the drawings)"),
       ("reasonable dimensions and accuracy requirements", "the report's stated aim: how link"
        " tolerances move the stitch length and the timing",
        "the accuracy analysis (docs/accuracy.md) and the report's accuracy section")),
    _r("JB-dynamics",
       "《JB型缝纫机动力学研究报告》 (Research report on the dynamics of the JB sewing machine)."
       " Shanghai Jiao Tong University, mechanism and machine dynamics group"
       " (上海交通大学机构学和机械动力学研究组), and the JB theory group of the Shanghai Sewing"
       " Machine Research Institute. Research report, May 1982.",
       "", "copy",
       ("1000 r/min", "the working speed at which the machine is analysed (72 positions, every"
        " 5 deg)", "the speed of the shipped JB files (`[speed] rpm`)"),
       ("phi = 90 deg at the needle bar's top", "the report's shaft-angle convention",
        "the JB files' `[convention]`, checked by `sewmech check`"),
       ("2.94 N over 135-155 deg (JB8-2 also 78-82 deg)", "the take-up's pull on the needle"
        " thread", "the JB files' `[[loads]]`: the magnitude, applied while the take-up draws"
        " its last 3 mm of thread in (135-150 deg in the files' own timing)"),
       ("14.7 N and 7.35 N over 90-175 deg", "the presser foot's force on the feed dog and the"
        " fabric's resistance to the feed", "the JB files' `[[loads]]`: the magnitudes, applied"
        " while the dog's teeth stand above the throat plate (the presser foot as an elastic"
        " load, the resistance against the dog's motion)"),
       ("the longest forward stitch", "the hardest case for the feed, at which the forces are"
        " computed", "the regulator setting of the report's dynamics section"),
       ("basic units; Newton-Raphson on loop closure; upper-shaft bearing reactions",
        "the report's methods: closed-form units after C. H. Suh [Suh-Radcliffe], loop"
        " equations for the feed, balancing with the bearings' reactions as objective",
        "the engine's units and loop solver, and the `bearings` balancing criterion")),
    _r("Sunkuev-balancing",
       "Сункуев Б. С., Радкевич А. В., Цветков Ю. М. «Уравновешивание механизмов швейных машин"
       " и полуавтоматов» (Sunkuev B. S., Radkevich A. V., Tsvetkov Yu. M., Balancing the"
       " mechanisms of sewing machines and semi-automatics). Вестник Витебского"
       " государственного технологического университета (Vestnik of Vitebsk State"
       " Technological University), p. 37 of the issue; the copy gives no year.",
       "", "copy",
       ("max|Qx| = max|Qy|", "the balancing criterion: the extra counterweight makes the peaks"
        " of the shaking force's two components equal", "the `delta-q` criterion of"
        " `sewmech balance`"),
       ("S_fact = 43.5 g cm", "the static moment of the counterweight on the class 1820's needle"
        " crank before balancing", "bartack-1820.toml, and its test"),
       ("S_opt = 107.6 g cm, S_add = 64.1 g cm", "the paper's computed optimum and extra"
        " counterweight", "compared with sewmech's answer in bartack-1820.toml and"
        " docs/balancing.md"),
       ("2.5-3 times S_add, a drilled lead insert; the crossing of x and y vibration velocity:"
        " 143 g cm; 110 -> 105.2 dBA", "how the extra counterweight is built and trimmed on the"
        " machine, and what it achieved", "`sewmech balance` (the insert),"
        " `sewmech trial-balance` (the crossing), its example measurements and tests"),
       ("elementary solids", "mass properties of links from cylinders, cones, boxes, spheres",
        "`[masses]` solids in machine files (formulas: [Meriam-Kraige])")),
    _r("Kozlov-take-up",
       "Козлов А. З. «Механизм нитепритягивателя вышивального полуавтомата» (Kozlov A. Z., The"
       " thread take-up mechanism of an embroidery semi-automatic). Research paper, 1990s (it"
       " cites works of 1991); the copy names no journal and has no drawings.",
       "", "copy",
       ("AB = 17.5 mm; BC/AB = 0.93, DC/AB = 0.62, AD/AB = 0.38; DE = l2/4; EF = 80 mm",
        "the design data of the double-crank take-up on a class 131 base", "embroidery-131.toml"),
       ("l2 = 124 mm; the eye at its top at phi = 65 deg", "thread drawn per cycle by the base"
        " machine, and the eye's top", "the tests of `sewmech.embroidery` and docs/embroidery.md"),
       ("(beta, alpha) = (35, 10) deg", "the pair closest to the base machine",
        "embroidery-131.toml, `sewmech embroidery-take-up`")),
    # ---- timing of stitch formation -----------------------------------------------------------
    _r("EC-household-machine",
       "《中国大百科全书》 (Encyclopedia of China), entry 家用缝纫机 (household sewing"
       " machine). Mirrored at the address given.",
       "http://outofmemory.cn/bake/4716441.html", "seen",
       ("206-210 deg", "the swing of the oscillating shuttle of the JA household machine per"
        " stitch (摆梭托推动摆梭旋转摆动206°~210°角)", "check 'shuttle swing'; the JB files' hook"
        " crank is sized for 208 deg"),
       ("crank-rocker plus oscillating slotted link (摆动导杆)", "the JA machine's hook drive",
        "the hook drive of the shipped JB files")),
    _r("Melnikov-seamstress",
       "Мельников И. «Секреты опытной швеи. Классификация и устройство» (Melnikov I., Secrets"
       " of an experienced seamstress: classification and construction of sewing machines).",
       "https://mybook.ru/author/ilya-melnikov/sekrety-opytnoj-shvei-klassifikaciya-i-ustrojstvo/"
       "citations", "seen",
       ("2-2.5 mm", "loop lift of Soviet household machines (Podolsk and others): the needle's"
        " rise from bottom dead centre when the shuttle point meets it, the point at the middle"
        " of the loop", "check 'loop lift when the shuttle point meets the needle'; the JB"
        " files' hook timing (2.2 mm)")),
    _r("NAVEDTRA-14218",
       "U.S. Navy training manual NAVEDTRA 14218: 'Timing the needle with the shuttle'"
       " (Singer 31-15), p. 186, and the check spring, p. 188.",
       "https://navyaviation.tpub.com/14218/css/Timing-The-Needle-With-The-Shuttle-186.htm",
       "seen",
       ("1/10 in = 2.54 mm; point 1/16 in = 1.6 mm above the eye", "the Singer 31-15's loop lift"
        " and where the shuttle point passes the needle", "check 'shuttle point above the needle"
        " eye at the meeting'; the JB files' shuttle axis (the point passes 1.6 mm above the"
        " eye)"),
       ("dog level with the plate as the needle point reaches the material", "feed timing of the"
        " Singer 31-15: the dog is on its downstroke", "check 'dog height when the needle point"
        " reaches the plate' (<= 0)")),
    _r("Navy-Singer-31-15",
       "U.S. Navy training manual (the tpub.com series 1ase2), p. 73: the Singer 31-15 sewing"
       " machine's data.", "http://www.tpub.com/1ase2/73.htm", "seen",
       ("7-32 stitches per inch: longest stitch 25.4/7 = 3.6 mm", "the Singer 31-15's stitch"
        " range", "the lower end of check 'longest forward/reverse stitch' (3.6-4.2 mm); the JB"
        " files' regulator travel")),
    _r("SewingMachineNut-2018",
       "'Sewing machine stitch length', Sewing Machine Nut (blog), January 2018: longest"
       " stitches measured on household machines.",
       "http://sewingmachinenut.blogspot.com/2018/01/sewing-machine-stitch-length.html", "seen",
       ("4.2 mm (6.0 SPI)", "the longest stitch of a class-15 clone (SewMor), measured; Kenmore"
        " 158 4.0 mm, Singer 328K 3.5 mm, Pfaff 130 2.9 mm", "the upper end of check 'longest"
        " forward/reverse stitch' (3.6-4.2 mm)")),
    _r("Sdelai-sam-1999",
       "«Сделай сам» (Do it yourself), 1999, no. 5, p. 10: the Podolsk household sewing"
       " machine.",
       "http://zhurnalko.net/=sam/sdelaj-sam_ogonek/1999-05--num10", "seen",
       ("1.2-1.5 mm", "how far the feed dog's teeth rise above the needle plate on the Podolsk"
        " household machine (Singer-15 derived), by fabric thickness", "check 'feed dog above"
        " the plate at the top of lift'; the JB files' dog height (1.35 mm)")),
    _r("Thread-holder-timing",
       "'Start and stop position', The Universal Thread Holder (web page on household machines).",
       "http://theuniversalthreadholder.com/start_and_stop_position.html", "seen",
       ("the take-up is at its highest when the needle has come back down a few millimetres"
        " (around 1/8 in)", "the take-up lever's top lags the needle's top dead centre",
        "checks 'take-up eye top after needle top' (> 0) and 'needle descent when the take-up"
        " eye is at its top' (read as 1.5-6 mm)")),
    _r("Juki-TL-2010Q",
       "JUKI TL-2010Q instruction manual, p. 21 (feed timing, loop lift).",
       "https://www.easymanua.ls/juki/tl-2010q/manual/119758?p=21", "seen",
       ("0 +- 0.2 mm", "where the needle tip is above the plate when the descending dog is flush"
        " with it (stitch setting 2)", "check 'dog height when the needle point reaches the"
        " plate' (<= 0)"),
       ("2.17 mm; dog 1.2 +- 0.1 mm above the plate", "loop lift and feed-dog height of a"
        " modern machine", "comparison only: inside the bands of the checks")),
    _r("Brother-S-7000DD",
       "Brother S-7000DD instruction manual, pp. 39-40 (feed-dog height, feed timing).",
       "https://manualsdump.com/en/manuals/brother-s-7000dd/53443/40", "seen",
       ("about 1 mm", "the needle tip above the plate when the descending dog is flush with it"
        " (standard subclass; about 3 mm for -03A)", "check 'dog height when the needle point"
        " reaches the plate' (<= 0: the dog is down by then)")),
    _r("Juki-how-it-works",
       "JUKI sewing machine museum, 'ミシンのしくみ' (How a sewing machine works).",
       "https://www.juki.co.jp/jp/muse/sew/mech02.html", "seen",
       ("the dog stays down while the needle is in the cloth", "feed timing",
        "check 'overlap of needle in fabric and dog above plate' (0 deg)"),
       ("the take-up goes down while the loop grows, then pulls the surplus back", "what the"
        " take-up does in one stitch", "the thread balance of `sewmech.thread`")),
    _r("SMI-feed-dog",
       "'How do you feed dog', Sewing Machines Institute (web article).",
       "https://www.sewingmachinesinstitute.com/single-post/how-do-you-feed-dog", "seen",
       ("level with or just below the plate as the needle enters", "the feed dog's place when"
        " the needle reaches the plate; it feeds only while the needle is out",
        "checks 'dog height when the needle point reaches the plate' and 'overlap of needle in"
        " fabric and dog above plate'")),
    # ---- the needle thread --------------------------------------------------------------------
    _r("Krasowska-take-up",
       "Krasowska R., Frydrych I., Rybicki M. (Technical University of Łódź), 'Possibilities"
       " for modelling control conditions of the thread by disc take-up in the lockstitch"
       " formation zone', Fibres & Textiles in Eastern Europe.",
       "https://studylib.net/doc/10969220/", "title",
       ("thread overfeed = supply - demand", "the quantity by which the take-up's control of"
        " the needle thread is judged, over the cycle", "the overfeed of `sewmech.thread` and"
        " its checks")),
    _r("US-10017890",
       "US patent 10,017,890 B2 (2018), 'Sewing machine and control method thereof'.",
       "https://ipiq.io/patents/5413022", "seen",
       ("the hook's necessary amount < the take-up's supply", "the upper thread the hook needs"
        " to go round the inner hook (about its outer circumference) must stay below what the"
        " take-up supplies", "check 'least overfeed while the shuttle enlarges the loop' (>= 0);"
        " the loop model (half the bobbin case's perimeter and twice its depth)")),
    _r("Juki-LK-1900B",
       "JUKI LK-1900B series instruction manual, p. 61 (thread take-up spring).",
       "https://www.easymanua.ls/juki/lk-1900b-series/manual/173834?p=61", "seen",
       ("8-10 mm", "stroke of the thread take-up (check) spring; its force at the start of"
        " the stroke 0.1-0.3 N", "check 'overfeed when the needle enters the fabric' (0-10 mm);"
        " `sewmech.thread.CHECK_SPRING_STROKE_MM`")),
    _r("Thread-consumption-301",
       "'Thread consumption' converter and table of industry formulas, Textile Tech Insight.",
       "https://textiletechinsight.com/converter-tools/thread-consumption/", "seen",
       ("C = 2 + 2 T S", "thread per inch of seam of stitch type 301 (T: thickness in inches, S:"
        " stitches per inch): l + t of needle thread and of bobbin thread per stitch",
        "check 'take-up reserve once the loop is cast off' (>= l + t); the consumption figure"
        " of the report")),
    _r("Malek-2020",
       "Malek S., Jaouachi B., Khedher F., Adolphe D., 'Sewing thread consumption for different"
       " lockstitches of class 300 using geometrical and multi-linear regression models', Autex"
       " Research Journal 20(4):415-425, 2020, doi:10.2478/aut-2019-0022.",
       "https://doi.org/10.2478/aut-2019-0022", "title",
       ("thread diameter in the stitch geometry", "a geometric consumption model with the"
        " thread's diameter", "the pi d / 2 bend term of"
        " `sewmech.thread.consumption_per_stitch` (its simplest form, our derivation)")),
    # ---- dimensions of the machine class -------------------------------------------------------
    _r("Juki-six-elements",
       "JUKI, 'Six major elements of sewing', section 1: momentum (stroke) of the needle bar.",
       "https://www.scribd.com/document/409995196/six-major-elements-of-sewing-unlocked-pdf",
       "seen",
       ("30.5 mm; 35 mm (DDL-5550H); 29 mm (DDL-5550A); 46.88 mm (LG-158)", "needle-bar strokes"
        " of JUKI lockstitch machines", "bartack-1820.toml: 35 mm stroke (needle crank 17.5"
        " mm)")),
    _r("Juki-DDL-8700",
       "JUKI DDL-8700 catalogue and specification table.",
       "https://www.juki.co.jp/industrial_e/download_e/catalog_e/ddl8700.pdf", "second-hand",
       ("30.7 mm", "needle-bar stroke of the DDL-8700 (none is published for the Singer 15 or"
        " the JA/JB)", "jb1-3.toml, jb8-2.toml: needle crank 15.35 mm"),
       ("5 mm; 5500 stitches/min; presser-foot lift 5.5 mm by hand, 13 mm by knee", "other"
        " figures of the same machine", "comparison only")),
    _r("Elna-presser-lift",
       "Elna Star Edition manual, p. 11 (presser-foot lift).",
       "https://manualshive.com/en/manual/elna/star-edition/2395070?page=11", "seen",
       ("5.5-6.2 mm, set at 6.0 mm", "the presser-foot lift of a household machine",
        "jb1-3.toml, jb8-2.toml: the needle point clears a 6 mm lift above the plate")),
    _r("JSPE-presser",
       "A study of the dynamic force of the presser bar on the feed bar of a sewing machine."
       " Journal of the Japan Society for Precision Engineering 53(3), p. 395, 1987.",
       "https://www.jstage.jst.go.jp/article/jjspe1986/53/3/53_3_395/_article/-char/en", "title",
       ("< 2 x the spring preload", "the dynamic presser-bar force on the feed bar stays below"
        " twice the presser spring's preload (from the abstract)", "the bound the JB files'"
        " presser-foot rate (2 N/mm) is chosen within: 17.4 N at the dog's full lift against"
        " 14.7 N at the plate")),
    _r("Home-speed",
       "Comparison of lockstitch power machine and the home sewing machine. BD Textile Mates,"
       " November 2022.",
       "https://bdtextilemates.blogspot.com/2022/11/comparison-of-lockstitch-power-machine-and-the-home-sewing-machine.html",
       "seen",
       ("1000-1200 stitches/min, the fastest <= 1500", "the working speeds of household"
        " machines", "the speed range the JB files' one-sided contacts must stay closed in"
        " (their feed-bar spring)"),
       ("<= 1500 stitches/min", "the fastest household machines", "the JB files' `[motor]`"
        " belt ratio: the motor's loaded speed puts the shaft at about 1400 rpm")),
    # ---- motors (the run in time) ---------------------------------------------------------------
    _r("OldSewinGear-motor",
       "Amped Up ... when bigger is not necessarily better. OldSewinGear (blog on vintage Singer"
       " and class 15 machines), 18 December 2012.",
       "http://www.oldsewingear.com/blog/amped-upbigger-is-not-always-better", "seen",
       ("1.0 A", "the motor of a belt-driven class 15 'Singer clone' household machine (a"
        " Singer 401's: 0.72 A)", "the JB files' `[motor]`: about 115 W taken at 115 V, so"
        " about 70 W at the shaft [estimate: 60 % efficiency]: the table's rated point")),
    _r("Nisley-Kenmore-motor",
       "Nisley E., 'Kenmore 158: Motor Speed vs. DC Voltage'. Softsolder (Ed Nisley's blog),"
       " 8 July 2014.",
       "https://softsolder.com/2014/07/08/kenmore-158-motor-speed-vs-dc-voltage/", "seen",
       ("about 8500 rpm; 300 mA unloaded, 500 mA loaded (110-120 V motor)", "the top speed of"
        " a household machine's universal motor belted to the machine, and its currents",
        "the JB files' `[motor]` table: its torque falls to the machine's light load near"
        " 10,000 rpm")),
    _r("Nisley-Kenmore-belt",
       "Nisley E., 'Kenmore 158: Current & Shaft Speeds vs. Motor RPM'. Softsolder (Ed"
       " Nisley's blog), 13 November 2014.",
       "https://softsolder.com/2014/11/13/kenmore-158-current-shaft-speeds-vs-motor-rpm/",
       "seen",
       ("belt reduction 11.1", "the motor's speed over the main shaft's in a household"
        " (zigzag) machine", "the range the JB files' belt ratio (7, for a faster straight-"
        "stitch machine) is chosen below")),
    _r("Leatherworker-clutch-motor",
       "Option C: Clutch Motor. leatherworker.net (forum blog on choosing a sewing machine"
       " motor).",
       "https://leatherworker.net/forum/blogs/entry/516-option-c-clutch-motor", "seen",
       ("an AC induction motor; 2-pole about 2800 rpm, 4-pole about 1400 rpm; a cork clutch"
        " face on a steel plate, pressed by the pedal", "what an industrial machine's clutch"
        " motor is", "bartack-1820.toml's `[motor]`: kind = \"clutch\", rated at 2800 rpm")),
    _r("Adafruit-clutch-motor",
       "Hacking an industrial sewing machine by adjusting the clutch motor. Adafruit blog,"
       " 8 November 2007.",
       "https://blog.adafruit.com/2007/11/08/hacking-an-industrial-sewing-machine-by-adjusting"
       "-the-clutch-motor/", "seen",
       ("the motor runs at 1750 rpm; 1/3 HP; the motor runs from the moment it is switched on,"
        " the pedal moves the clutch onto it", "an industrial machine's clutch motor",
        "bartack-1820.toml's `[motor]`: 250 W (1/3 HP), running before the clutch engages")),
    # ---- standards, textbooks and methods -----------------------------------------------------
    _r("Friction-handbook",
       "Oberg E. et al., Machinery's Handbook, section on friction: coefficients of friction of"
       " metals, dry and lubricated. Industrial Press, New York.",
       "", "textbook",
       ("mu 0.05-0.15", "steel on steel in boundary lubrication (oiled plain bearings and"
        " cams)", "the JB files' `[friction]` coefficient 0.08 [estimate within the range]")),
    _r("ISO-286",
       "ISO 286-1:2010, Geometrical product specifications (GPS) - ISO code system for"
       " tolerances on linear sizes - Part 1: Basis of tolerances, deviations and fits. Table 1.",
       "https://www.iso.org/standard/45975.html", "textbook",
       ("IT5-IT13 by nominal size", "standard tolerance grades (um) for sizes up to 500 mm",
        "`sewmech tolerance` and tolerance files (`it_grade`); the report's accuracy section"
        " at IT9")),
    _r("Suh-Radcliffe",
       "Suh C. H., Radcliffe C. W., Kinematics and Mechanism Design. John Wiley & Sons, New"
       " York, 1978 (Chinese translation 《运动学和机构设计》, China Machine Press, 1982).",
       "", "textbook", background=True),
    _r("Meriam-Kraige",
       "Meriam J. L., Kraige L. G., Engineering Mechanics: Dynamics, appendix on mass moments of"
       " inertia. John Wiley & Sons.",
       "", "textbook", background=True),
    _r("Freudenstein-1955",
       "Freudenstein F., 'Approximate synthesis of four-bar linkages', Transactions of the ASME"
       " 77:853-861, 1955 (reprinted in Resonance 15(8):740-767, 2010).",
       "", "title",
       ("K1 cos(theta4) - K2 cos(theta2) + K3 = cos(theta2 - theta4)", "the four-bar's"
        " input-output equation, linear in K1, K2, K3: three precision points fix a function"
        " generator, more give a least-squares fit; Chebyshev's spacing of the points",
        "`sewmech synthesize function` (sewmech.design.synthesis)"), background=True),
    _r("Burmester-1888",
       "Burmester L., Lehrbuch der Kinematik. Erster Band: Die ebene Bewegung. A. Felix,"
       " Leipzig, 1888.",
       "", "textbook",
       ("centre-point and circle-point curves", "the fixed and moving pivots of the dyads that"
        " guide a body through four given positions", "`sewmech synthesize motion` with four"
        " poses (sewmech.design.burmester)"), background=True),
    _r("Sandor-Erdman-1984",
       "Sandor G. N., Erdman A. G., Advanced Mechanism Design: Analysis and Synthesis, Volume 2."
       " Prentice-Hall, Englewood Cliffs, 1984.",
       "", "textbook",
       ("W (e^{i beta} - 1) + Z (e^{i alpha} - 1) = delta", "the dyad's standard form and, for"
        " four positions, its compatibility condition (a triangle closure); prescribed-timing"
        " path generation by the same form", "sewmech.design.burmester: the Burmester curves"
        " and the exact start of `sewmech synthesize path`"), background=True),
    _r("Grashof-1883",
       "Grashof F., Theoretische Maschinenlehre, Band 2. L. Voss, Leipzig, 1883.",
       "", "textbook",
       ("s + l <= p + q", "a four-bar has a link that turns fully relative to the others when"
        " the shortest and longest lengths add up to no more than the other two",
        "the Grashof type every synthesis reports and the crank inputs it prefers"),
       background=True),
    _r("Huangfu-Hall-2018",
       "Huangfu Q., Hall J. A. J., 'Parallelizing the dual revised simplex method', Mathematical"
       " Programming Computation 10:119-142, 2018 (HiGHS, scipy.optimize.linprog's solver).",
       "https://doi.org/10.1007/s12532-017-0130-5", "title",
       ("the dual revised simplex method", "the solver of the min-max balancing's linear"
        " programme", "`sewmech influence-balance --solver minmax`"), background=True),
    _r("Berkof-Lowen-1969",
       "Berkof R. S., Lowen G. G., 'A new method for completely force balancing simple"
       " linkages', ASME Journal of Engineering for Industry 91(1):21-26, 1969.",
       "https://asmedigitalcollection.asme.org/manufacturingscience/article-abstract/91/1/21/"
       "427778", "title",
       ("conditions for a complete force balance of a four-bar by counterweights", "the method"
        " of linearly independent vectors", "a closed form the balancing tests check sewmech"
        " against"), background=True),
    _r("Kloss-formula",
       "Kloss's formula: the simplified torque-slip curve of the induction motor, as"
       " electrical-machines textbooks give it (e.g. Fischer R., Elektrische Maschinen, Hanser,"
       " Munich).",
       "", "textbook",
       ("T(s) = 2 T_b s s_b / (s^2 + s_b^2)", "an induction motor's torque against its slip"
        " through its breakdown point (T_b, s_b); with the rated point it gives s_b ="
        " s_r (k + sqrt(k^2 - 1)), k = T_b / T_r", "`[motor]` kind = \"induction\" and"
        " \"clutch\" (sewmech.engine.motor)"), background=True),
)

BY_KEY: dict[str, Reference] = {r.key: r for r in REFERENCES}


def keys_in(text: str) -> list[str]:
    """The keys cited in ``text``, in order of first appearance, each once."""
    return list(dict.fromkeys(k for k in KEY_PATTERN.findall(text) if k not in NOT_KEYS))


def cited(text: str) -> list[Reference]:
    """The entries of the keys cited in ``text`` (a key that is not in the list is left out;
    the tests keep every key of the package resolvable)."""
    return [BY_KEY[k] for k in keys_in(text) if k in BY_KEY]


def _md(text: str) -> str:
    return text.replace("|", "\\|")


def markdown() -> str:
    """docs/references.md: every entry with its facts."""
    out = ["# References", "",
           "Every published fact that sewmech checks a machine against or takes a value from, and",
           "where it comes from. The checks, the shipped machine files, the report, the",
           "interactive page and these docs cite each source by the short key in square",
           "brackets. How far each source was checked is said with it: only figures seen in a",
           "source (or, where said, second-hand) are used; a source read by title only gives a",
           "method or a quantity, never a number. Entries marked *background* give a method or",
           "a formula rather than a value.", "",
           "This page is written from `sewmech.sewing.references`",
           "(`python -m sewmech.sewing.references > docs/references.md`); a test keeps it so.",
           ""]
    for r in REFERENCES:
        out.append(f"## [{r.key}]" + (" (background)" if r.background else ""))
        out.append("")
        out.append(r.source)
        out.append("")
        if r.url:
            out.append(f"<{r.url}>")
            out.append("")
        out.append(f"Checked: {CHECKED[r.checked]}.")
        out.append("")
        if r.facts:
            out.append("| value | what it is | how sewmech uses it |")
            out.append("|---|---|---|")
            out += [f"| {_md(f.value)} | {_md(f.what)} | {_md(f.used)} |" for f in r.facts]
            out.append("")
    return "\n".join(out)


if __name__ == "__main__":  # pragma: no cover - writes docs/references.md
    print(markdown(), end="")
