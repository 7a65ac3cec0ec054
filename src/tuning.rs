//! Every constant the solver was tuned with, in one place, each with the evidence for its
//! value (FCLib figures are at tolerance 1e-8 unless said otherwise). Definitions that are
//! not choices (the C API's limits) stay where they are
//! defined; the ADMM loop's own constants stay beside the loop in `admm`.

/// Steps of a contact's projected fixed point in a Gauss-Seidel sweep, when the contact
/// neither separates nor sticks (`gauss_seidel/contact.rs`). On a dumped step of a
/// 100-brick wall after a ball hit it (561 contacts), 100 sweeps end at 1.2e-2 with one
/// step, 8.7e-3 with five and 8.5e-3 with the contact solved exactly; five steps cost four
/// times as much time a sweep (0.38 ms against 0.09 ms on a step of the wall at rest), so
/// one step gives the better
/// answer within any budget.
pub const GAUSS_SEIDEL_INNER: usize = 1;

/// Gauss-Seidel sweeps are first measured after this many (then after each doubling): a
/// measure costs 2 to 3 sweeps, and within an engine's budget of 20 to 60 sweeps measures
/// after sweeps 1 and 2 took a tenth of it. A budgeted solve also runs at least this many
/// sweeps, past its time limit if need be: fewer leave errors of 0.3 to 1 on the steps
/// where a wall or a pile first lands (their new contacts start from no impulse), worse
/// than an engine's own solver, and boxes of a 512-box bin sank 1.4 m into its floor when
/// setup had left no time for any sweep.
pub const GAUSS_SEIDEL_FIRST_MEASURE: usize = 4;

/// A budgeted solve's sweeps over at most [`DENSE_MAX`] contact rows, with every joint
/// row solved together, try Newton on the contacts' dense Delassus form once, after
/// [`GAUSS_SEIDEL_FIRST_MEASURE`] sweeps (`gauss_seidel/dense_contacts.rs`), for at most
/// this many steps, to this share of the tolerance by the form's own measure (the sweeps'
/// measure, on the whole problem, judges the answer).
pub const DENSE_CONTACTS_NEWTON_STEPS: usize = 30;
/// See [`DENSE_CONTACTS_NEWTON_STEPS`].
pub const DENSE_CONTACTS_TIGHTER: f64 = 1e-2;
/// Newton on few contacts is first tried only with this many sweeps' time left (later
/// attempts at the same number of contacts, with what the last one took). On a 20-link
/// chain striking a box (8 contacts, 60 joint rows solved together) forming the dense form
/// and its 5 Newton steps cost about 1e6 instructions, 25 to 30 sweeps.
pub const DENSE_CONTACTS_FIRST_SWEEPS: f64 = 30.0;

/// Once no handover can follow (too little time left), a Gauss-Seidel checkpoint is
/// measured only when the measure costs at most this share of the sweeps since the last
/// one. Such a measure only keeps the best iterate and sees the tolerance met, and it costs
/// 2 to 3 sweeps (it recomputes the velocities and measures every contact: 75 against 38
/// us on a 900-contact pyramid step, 220 against 85 us on a 2 300-contact bin step). The
/// measures at 4, 8 and 16 sweeps took 6 to 9 sweeps' time of an engine's budget of 20 to
/// 60 (docs/perf/engine-setup-2026-11-27).
pub const GAUSS_SEIDEL_MEASURE_SHARE: f64 = 0.1;

/// A Gauss-Seidel sweep that moved no impulse by more than this share of the tolerance
/// times the largest impulse is measured, however dear the measure, and the next such
/// measure waits for a sweep this many times stiller: engines stop their own sweeps so. A
/// chain of 20 links on a box, solved to 1e-6 and below within 2 sweeps, went on sweeping
/// to its budget. On the sweeps' slow scenes the error is 5 to 10 times the stillness (a
/// pyramid of 120 boxes: sweeps that moved by 5e-5 to 6e-5 of the largest impulse measured
/// 3e-4 to 8e-4), so stillness at the tolerance itself would cost them a measure a step.
pub const GAUSS_SEIDEL_STILL: f64 = 0.1;

/// A budgeted solver whose joint rows outnumber its contact rows, and which its sweeps take
/// one at a time (not together: [`JOINT_BLOCK_FLOPS`]), once kept across this
/// many solves, builds its islands after the sweeps of the next one and goes straight to
/// them from then on. Sweeps carry a correction along a chain of joints one link a sweep,
/// where the factorized system solves the joint rows exactly. In Bullet under
/// the 100-iteration solver's time, the share of steps whose answer measures below that
/// solver's went from 26 to 86% on a 20-box chain, 2 to 97% on a 7-hinge arm, 0 to 74% on
/// a pendulum and 39 to 61% on a ragdoll tumbling down stairs
/// (docs/perf/engine-setup-2026-11-27). After 1 solve instead of 2, the ragdoll (94 solvers
/// built in 120 steps) paid for islands it used once: 46 to 44%.
pub const BUDGET_JOINTED_AFTER: usize = 2;

/// A budgeted solve's sweeps solve the joints' rows together (their Delassus matrix
/// factorized within its profile, `gauss_seidel/joint_block.rs`) when every row is an
/// equality and that factorization costs at most about this many multiply-adds (a few
/// tens of microseconds); otherwise one at a time. Such a solver, kept, stays on its
/// sweeps ([`BUDGET_JOINTED_AFTER`] is for rows swept one at a time). In Bullet under the
/// 100-iteration solver's time, the steps of a 20-box chain on point-to-point joints
/// answered below that solver went from 80 to 85% to 93 to 96%, at median errors of 1e-11
/// to 1e-15 (the chain's rows: 60, about 9 000 multiply-adds). Solving the equality rows
/// together beside bounded rows (a ragdoll's joint limits) made it worse: 41 to 52% of
/// steps below, against 24 to 37% (docs/perf/engine-budget-2026-11-28).
pub const JOINT_BLOCK_FLOPS: f64 = 2e5;

/// The profile (multiply-adds of its factorization) above which the joint rows solved
/// together are reordered first (reverse Cuthill-McKee). On a 20-link chain handed in
/// Bullet's order (9 000, against about 1 000 reordered) ordering cost as many
/// instructions as a rebuilt step's sweeps then saved; an order an engine scrambled on a
/// longer chain or tree (the cost grows with the square of its width) may otherwise pass
/// [`JOINT_BLOCK_FLOPS`] and leave its rows to one-at-a-time sweeps.
pub const JOINT_BLOCK_REORDERED_FLOPS: f64 = 2e4;

/// Gauss-Seidel sweeps go on while, at the rate of their last doubling, they would meet
/// the tolerance within this many times the time they took so far (two more doublings at
/// most); beyond that ADMM and Newton finish sooner (the wall at rest at 1e-4: the sweeps
/// would need 1 024 sweeps, 97 ms, where ADMM needs 28 ms).
pub const GAUSS_SEIDEL_PATIENCE: f64 = 3.0;

/// Sweeps before a matrix-free coupled solve are first judged for a handover after this
/// many (`gauss_seidel::Yield::CoupledCost`).
pub const GAUSS_SEIDEL_JUDGED_LATE: usize = 128;

/// The least a matrix-free coupled solve costs, in Gauss-Seidel sweeps' time: piles of
/// 25 000 spheres took 550 to 2 250 ADMM iterations at 1e-4, each of 3 to 4 conjugate-
/// gradient iterations (a product with M, H and H^T, and the preconditioner), about ten
/// sweeps' time (docs/perf/piles-2026-11-27).
pub const GAUSS_SEIDEL_MATRIX_FREE_SWEEPS: f64 = 5000.0;

/// Gauss-Seidel sweeps hand over only with at least this many sweeps' time left: the
/// coupled solve must first be built (a dumped wall step: 1 to 4 ms, 10 to 60 sweeps),
/// and ADMM needs 600 to 1 600 iterations of 3 to 4 sweeps' time each at 1e-4 on the
/// dumped wall and bin steps after impact. Handing over with 100 sweeps' time left, the
/// wall's step ended at 0.15 within 7.5, 25 and 100 ms, where the sweeps alone reach
/// 7.5e-3, 1.5e-3 and 3.1e-4.
pub const GAUSS_SEIDEL_HANDOVER_SWEEPS: f64 = 2000.0;

/// ... and on an engine's first step (a new solver's first solve, from a warm start) with
/// this many. A scene starts at rest more often than not, where ADMM and Newton solve the
/// first step in a few iterations (a 120-box pyramid in Bullet: 14, about 10 ms), and every
/// later step starts from its answer: a resting scene whose first step is solved then
/// takes each warm start as it is. Under a 16 ms budget that pyramid's steps went from
/// 15.8 ms at median errors of 1e-3 (every step unsolved, 9 mm of drift) to 0.63 ms at
/// 2e-5 (every step solved, no drift); without a budget they cost 0.37 ms
/// (docs/perf/engine-resting-budget-2026-11-27). Every later solve keeps the bar above.
pub const FIRST_STEP_HANDOVER_SWEEPS: f64 = 200.0;

/// Systems of at most this many unknowns are factorized densely: below a few dozen
/// unknowns a dense Cholesky or LU costs less than a sparse one's analysis, bookkeeping and
/// allocations (an island of a box on the ground has 6 velocities and 12 contact rows).
///
/// The same bound says when a problem starts with Newton: when the systems of its Newton
/// step are dense. An island whose mass matrix and Delassus matrix both are
/// (`n <= DENSE_MAX`, `3 nc <= DENSE_MAX`) is solved by Newton on its dense Delassus form,
/// ADMM taking over only if that fails; a problem solved whole whose global Newton system is
/// (velocities, contact rows and joints; the local form: contact rows) starts with a
/// Newton phase of at most [`NEWTON_FIRST_STEPS`] steps. A dense Newton step costs about as
/// much as a few ADMM iterations, and Newton needs 4 to 10 of them where ADMM needs about
/// 100 (the small Rover files: 3 to 4x less time, median of 2000 solves).
pub const DENSE_MAX: usize = 48;

/// Sparse LU factorizations (`linsys::Lu`) of at least this many unknowns are supernodal
/// (dense kernels on groups of columns); below, faer chooses from the pattern. Its choice
/// took the simplicial factorization for a 100-brick wall's reduced Newton matrix (600
/// unknowns), whose steps then took 3 times as long (a dumped step at 1e-8, 4 000
/// iterations: 14.2 s against 4.9 s), and Newton phases on Box_Stacks-i1000-444-8 and
/// -557-13 twice as long; forced on the small islands of Capsules-i100-889 (local form),
/// the supernodal factorization made the solve about 30% slower.
pub const LU_SUPERNODAL_MIN: usize = 256;

/// The error measure is evaluated every this many iterations (and whenever the cheap
/// residual test passes): it costs a few matrix-vector products, an iteration about one solve.
pub const ERROR_CHECK_INTERVAL: usize = 5;

/// ADMM hands over to the Newton phase once the error measure is at or below this: by then
/// it has identified which contacts are open, sticking or sliding, where Newton converges
/// in a few steps.
pub const HANDOVER_ERROR: f64 = 1e-6;

/// ... or when the error has not halved over this many evaluations (ERROR_CHECK_INTERVAL
/// iterations each): ADMM has stalled, and Newton may still finish from there.
pub const HANDOVER_STALL_CHECKS: usize = 20;

/// The handover's cost model (docs/algorithms.md §9.3): ADMM hands over only when a Newton
/// phase of this many steps, each costing [`NEWTON_STEP_ITERATIONS`] ADMM iterations, is
/// predicted to cost less than ADMM's remaining iterations at its measured rate. Newton
/// needs 1 to 5 steps from most handovers (FCLib Box_Stacks: 3; an engine's pile of 31
/// bricks: 1 in 72 of 179 phases, median 3).
pub const NEWTON_EXPECTED_STEPS: f64 = 4.0;

/// ... and a phase from a stall above the handover error (a rescue, from farther away)
/// this many: 6 to 197 steps over the 13 such phases of the FCLib set (median 57), 21 to
/// 28 on a 2 845-contact sphere pile. With 30, a slow ADMM within 1 500 iterations of the
/// tolerance keeps going (the pile: 28 Newton steps of 60 iterations' cost each, where
/// ADMM needed about 1 300 iterations).
pub const NEWTON_RESCUE_STEPS: f64 = 30.0;

/// A Newton step's cost in ADMM iterations: its factorization against an iteration's
/// triangular solves. Measured at handovers with the unreduced system: 55 to 85 on
/// Box_Stacks, 60 on a 2 845-contact sphere pile, 35 to 90 on an engine's pile of 31
/// bricks, 10 to 25 on Capsules; with the system reduced to the velocities, 16 to 28 on
/// Box_Stacks and about 85 on the pile (its LU's column ordering fills more there). A constant, not the cost measured on the problem at hand:
/// a decision taken on wall-clock times would make the same solve differ from run to run
/// with the machine's load (two solves on eight threads did). With 4 expected steps the
/// handover waits while ADMM is within 200 iterations of the tolerance, as the rule tuned
/// before it did (FCLib set at 1e-8, `auto` against ADMM alone: median time ratio 1.28
/// without such a rule, 1.06 with 200 iterations).
pub const NEWTON_STEP_ITERATIONS: f64 = 50.0;

/// ... and where the step's system is dense (the reduced global system: velocities and
/// joints; the local one: contact rows; at most [`DENSE_MAX`] unknowns), this many: such a
/// step costs about as much as a few ADMM iterations.
pub const NEWTON_DENSE_STEP_ITERATIONS: f64 = 5.0;

/// A Newton phase after a handover below the handover error may take the steps that cost,
/// at [`NEWTON_STEP_ITERATIONS`] each, this many times the iterations ADMM predicted it
/// still needed; past them it ends as a failed phase. `auto` then costs at most about that
/// much more than ADMM alone (an engine's pile of 31 bricks had phases of 20 to 98 steps,
/// 0.05 to 0.35 s, where ADMM needed 10 ms). A rescue (a handover on a stall above the
/// handover error) is not bounded, and comes only from more than 10 times above the
/// tolerance (`HandoverMonitor::newton_budget`).
pub const NEWTON_BUDGET: f64 = 1.0;

/// Newton steps allowed per Newton phase with ADMM to fall back on. Newton itself stops a
/// phase that has not cut its best error by 10% in 60 steps; on the Box_Stacks files it
/// needs 80 to 110 steps from ADMM's handover, so caps of 50 or 100 failed phases that
/// were about to converge (FCLib set at 1e-8: 8.2 s in all with 50, 6.7 s with 200, 5.2 s with 400).
pub const NEWTON_MAX_STEPS: usize = 400;

/// A global Newton phase from ADMM gives up once its steps without progress have cost about
/// this many ADMM iterations, at a step's cost predicted from the factor's analysis
/// (`ProblemSplitting::newton_stall`), and after [`NewtonTuning::stall`] steps at most: the
/// 60-step window was chosen on Box_Stacks, where a step costs 8 to 11 iterations
/// (predicted; 9 to 11 measured), and keeps it. On sphere piles of 2 800 contacts a step
/// costs 74 to 115 (predicted; 52 to 68 measured), a window of 5 to 8 steps: failed phases
/// there had run 60 steps past their best at 60 ms a step, up to 4 s where ADMM alone took
/// 2 s, while the phases that solve those piles converged within the shorter window too
/// (docs/perf/newton-window-2026-11-28).
pub const NEWTON_STALL_ITERATIONS: f64 = 600.0;

/// ... but at least this many steps.
pub const NEWTON_MIN_STALL: usize = 5;

/// The solver works to `tolerance * (1 - ROUND_OFF_MARGIN)`: the measure of a solution
/// computed elsewhere (another summation order, another program) differs by round-off, and
/// a solution reported solved must meet the tolerance there too. At mass ratio 1e4 the local
/// measure of one solution read 9.99964e-9 in cadmm and 1.0000037e-8 recomputed, a
/// relative difference of 4e-5.
pub const ROUND_OFF_MARGIN: f64 = 1e-3;

/// The islands' first solve floors its complementarity denominator at this share of the
/// free motion's contact velocities (`measure::free_contact_velocity`, times the island's
/// `sqrt` share, docs/algorithms.md §12): far below any island whose impulses or velocities
/// are not zero, so that the floor changes nothing there, and far above the round-off of
/// one whose answer is zero (a wall's row falling together: impulses of 6e-16 and
/// residuals of 6e-19 measured 9e-4 against their own size, and the island ran to the
/// iteration limit). With the whole free velocity as the floor, islands stopped looser and
/// the refine rounds cost up to 70% more iterations on the Box_Stacks files.
pub const FREE_CONTACT_SHARE: f64 = 1.5e-8;

/// Rounds in which islands are solved again to a tighter tolerance when their assembled
/// solution misses the whole problem's tolerance (docs/algorithms.md §12).
pub const ISLAND_ROUNDS: usize = 4;

/// A Newton step solved through the system reduced to the velocities is refined on the
/// unreduced residual up to this many times ...
pub const REDUCED_REFINEMENTS: usize = 3;

/// ... until that residual is at most this fraction of the right-hand side; otherwise the
/// unreduced system is solved instead. An inexact Newton direction with this forcing term
/// keeps the local convergence far below any tolerance a caller can ask for.
pub const REDUCED_RESIDUAL: f64 = 1e-10;

/// Steps of the first Newton phase of a small problem.
pub const NEWTON_FIRST_STEPS: usize = 50;

/// rho stays within `[rho0 / RHO_RANGE, rho0 * RHO_RANGE]`: beyond that the factorization of
/// `M + rho H H^T` (or `W + rho I`) loses the other term to round-off.
pub const RHO_RANGE: f64 = 1e8;

/// Absolute tolerance of ADMM's residual test: this value at error tolerances of
/// [`RESIDUAL_EPS_ABS_FROM`] and above, scaled with the tolerance below that (the relative
/// part is the tolerance itself).
pub const RESIDUAL_EPS_ABS: f64 = 1e-6;
/// See [`RESIDUAL_EPS_ABS`].
pub const RESIDUAL_EPS_ABS_FROM: f64 = 1e-3;

/// When an island fails after a Newton phase and ADMM resumes, the next handover waits for
/// an error this many times below where that phase failed (and for a stall twice as long):
/// a Newton phase then costs a bounded share of the solve.
pub const HANDOVER_RETRY_FACTOR: f64 = 1e-2;

/// Islands solved again after the assembled solution missed the tolerance get at least
/// this factor on their tolerance (more when the miss was larger).
pub const ISLAND_TIGHTENING: f64 = 0.5;

/// `||H r|| <= NULL_SPACE ||H||_F ||r||`: the impulses push (almost) nothing
/// (infeasibility certificate, docs/algorithms.md §13).
pub const NULL_SPACE: f64 = 1e-6;
/// `-r . u~ >= DEFECT ||r|| max(||u~||, ||u_free||)`: they meet approaching velocities.
pub const DEFECT: f64 = 0.1;

/// Regularization of the joint block of the quasi-definite system `[[M + rho H H^T, G],
/// [G^T, -JOINT_DELTA I]]`: small enough to leave the joint residual below the tolerances
/// asked for, large enough for the LDL^T to stay quasi-definite.
pub const JOINT_DELTA: f64 = 1e-9;

/// Cap of the regularization when Newton alone solves a small island from a cold start
/// (`LocalNewton::solve_measured`): the islands are well scaled and mostly regular, so a
/// nearly exact first step identifies the contact states; a singular system still gets its
/// regularization strengthened tenfold per failed step.
pub(crate) const SMALL_ALPHA_CAP: f64 = 1e-6;

/// Tuning shared by both solvers (see the module docs of `newton::local` for the reasoning).
#[derive(Debug, Clone, Copy)]
pub(crate) struct NewtonTuning {
    /// Armijo constant of the residual-norm decrease test.
    pub sigma: f64,
    /// Smallest line-search step before the step is retried with more regularization.
    pub min_step: f64,
    /// Smallest relative proximal regularization (keeps the matrix invertible).
    pub alpha_min: f64,
    /// Largest relative proximal regularization (beyond it the step is declared failed).
    pub alpha_max: f64,
    /// Cap of the residual-driven part of the regularization.
    pub alpha_cap: f64,
    /// Regularization per unit of relative residual `||R|| / impulse scale`.
    pub alpha_per_residual: f64,
    /// Iterations without an improvement by [`NewtonTuning::progress`] before giving up.
    pub stall: usize,
    /// An error at most this share of the one at the last improvement is an improvement.
    pub progress: f64,
    /// Number of past merits the non-monotone line search compares with.
    pub window: usize,
    /// Steps taken at most after the error measure meets the tolerance, for the unit-free
    /// residual to meet it too.
    pub confirm: usize,
}

/// The values used (chosen on the random box stacks of the tests).
pub(crate) const NEWTON: NewtonTuning = NewtonTuning {
    sigma: 1e-4,
    min_step: 1.0 / 1024.0,
    alpha_min: 1e-14,
    alpha_max: 1e8,
    alpha_cap: 1e-2,
    // The relative residual runs at 0.1 to 0.9 times the error measure on the FCLib files
    // (median about 0.2 on Box_Stacks): 3 keeps the regularization near the level it had
    // when it followed the measure (the set's iterations and time unchanged overall).
    alpha_per_residual: 3.0,
    // Progress is a 10% cut of the best error, not any cut: failed phases on Box_Stacks
    // crept on for up to 246 steps (9.3e-6 to 8.7e-6 on i1000-547-14), while converging
    // ones went at most 47 steps without a 10% cut (i1000-557-13, islands off) and 34
    // without any; a window of 30 failed that phase (7 times the iterations).
    stall: 60,
    progress: 0.9,
    window: 8,
    confirm: 2,
};

/// A matrix-free v-update may stop once its residual is below this share of the last
/// measured error (in the units of the measure's equation term, which the residual adds
/// to): from there the inexactness costs at most a tenth of the error ADMM drives down.
pub const PCG_ERROR_SHARE: f64 = 0.1;

/// ... and, before a first measure, to this residual relative to the right-hand side.
pub const PCG_FIRST_RELATIVE: f64 = 1e-2;

/// No v-update is asked for a relative residual below this (round-off in the products).
pub const PCG_RELATIVE_FLOOR: f64 = 1e-14;

/// Most conjugate-gradient iterations per v-update; a solve stopped there is inexact, which
/// the next measured error shows (block Jacobi reaches 1e-8 from zero in about 30 on the
/// piles).
pub const PCG_MAX_ITERATIONS: usize = 300;

/// Conjugate-gradient iterations per warm-started v-update that the `auto` cost model
/// expects (docs/algorithms.md §14): measured 3.9 to 4.9 on the sphere piles of 2 816 to
/// 25 271 contacts. With 10, `auto` factorized the 10 050-contact irregular pile and took
/// 36 s to 1e-4 (61 ms an iteration, with its Newton phases), where the matrix-free
/// backend, which 5 chooses, took 15 s (both single runs beside other work).
pub const PCG_EXPECTED_ITERATIONS: f64 = 5.0;

/// `auto` never factorizes a v-update system whose factor holds more entries than this
/// (400 MB per factor; the solver keeps up to three, one per recent rho).
pub const FACTOR_MAX_ENTRIES: usize = 50_000_000;

/// `auto` keeps factorizing v-update systems whose factor holds fewer entries than this:
/// such a factorization costs milliseconds, and the Newton phase that the direct backend
/// keeps finishes tight solves in far fewer iterations than ADMM alone (384-contact sphere
/// lattice at 1e-8: 293 iterations, 0.08 s factorized with Newton, against 8 205
/// iterations, 0.71 s matrix-free; its factor holds 1.0e5 entries, that of the
/// 2 800-contact 10 x 10 x 10 lattice 2.1e6).
pub const MATRIX_FREE_MIN_FILL: usize = 1_000_000;

/// Each matrix-free v-update shrinks the residual of its warm start (the last velocity) by
/// this factor, unless it is already below [`PCG_ERROR_SHARE`] of the error: the error of
/// each inexact step is then a fraction of the step, which vanishes as ADMM converges. At
/// 0.3 the steps take fewer conjugate-gradient iterations but ADMM more iterations, for
/// more time in all (to 1e-6, irregular pile of 2 845 contacts: 1 080 iterations, 1.5 s
/// at 0.1, 1 565 and 1.7 s at 0.3; lattice pile of 2 816: 8 710 and 5.5 s, 11 650 and
/// 5.8 s).
pub const PCG_REDUCTION: f64 = 0.1;

/// A matrix-free v-update starts from the residual its last solve left (plus the change of
/// right-hand side) instead of a product with the operator, except every this many solves,
/// where the product brings round-off in the recurrence back to the true residual.
pub const PCG_TRUE_RESIDUAL_EVERY: usize = 8;

/// The matrix-free products run on the solver's threads (`Settings::threads`, for a problem
/// solved whole) when `M` and `H` hold at least this many entries together: below,
/// starting scoped threads twice per conjugate-gradient iteration costs what it saves (2
/// threads against 1, to 1e-4: the 2 816-contact lattice pile, 3.4e4 entries, 1.6x slower;
/// the 10 200-contact lattice, 1.2e5, even; the 10 050-contact irregular pile, 3.6e5, 1.13x
/// faster; the 25 271-contact one, 8.6e5, 1.2x faster; single runs).
pub const PARALLEL_MIN_ENTRIES: usize = 200_000;

/// The matrix-free products of such a system split its contacts into this many fixed
/// chunks, each scattering into its own buffer: the threads run the chunks, and the sum
/// does not depend on how many there are (beyond this many, threads sit idle in them).
pub const PRODUCT_CHUNKS: usize = 4;

/// The matrix-free products store a contact's three columns on one shared list of rows
/// when that stores at most this many values per entry of H (zeros where a column misses a
/// row of the union); above, each column keeps its rows. A rigid body's contact rows share
/// their pattern (ratio 1.0 on the irregular piles); the axis-aligned lattice piles have
/// one entry per body in each column (ratio 3, where the shared rows made the 25 024-contact
/// pile 1.04x slower to 1e-4 than products by rows and columns, and the 100 776-contact one
/// 1.07x).
pub const SHARED_ROWS_MAX_STORED: f64 = 1.5;

/// A warm-started global solve leaves out of its v-update system the contacts with no
/// impulse whose normal velocity at the warm velocity exceeds this fraction of the largest
/// one (predicted open; brought back when their velocity turns negative). An engine's
/// open contacts within its margin otherwise slow ADMM down: 300 steps of the demo with
/// its pyramid's side faces 5 mm apart, replayed, took ADMM alone 31 836 iterations with
/// them against 8 416 with them removed.
pub const SCREEN_RATIO: f64 = 1e-3;

// Factorizations and small dense solves.

/// Numeric factors of a sparse x-update system kept for recently used rho values: a rho
/// rule that moves back to a value it left (or oscillates between two) finds its factor
/// instead of refactorizing, and a third covers the step between them. Each holds the
/// whole fill, so more would cost memory for a rare reuse (see [`FACTOR_MAX_ENTRIES`]).
pub const FACTOR_CACHE: usize = 3;

/// The quasi-definite `L D L^T` (joints) corrects a pivot whose sign is wrong or whose
/// magnitude is at most this (faer's dynamic regularization): far below the joint block's
/// own regularization [`JOINT_DELTA`], so that only pivots round-off drove to zero or
/// across it are touched.
pub const LDLT_PIVOT_MIN: f64 = 1e-13;

/// ... and makes it this, with its expected sign: below [`JOINT_DELTA`] too, an error the
/// step of iterative refinement after each solve corrects along with the regularization.
pub const LDLT_PIVOT_REPLACEMENT: f64 = 1e-10;

/// Largest diagonal block the block Jacobi preconditioner of the conjugate gradients
/// factorizes (a rigid body has 6 velocities; a body with a few extra coordinates still
/// fits); larger components of M's graph fall back to their diagonal. Also the most
/// velocities a body of a distributed problem may have.
pub const BLOCK_MAX: usize = 12;

/// Tikhonov regularization of Anderson acceleration's normal equations, relative to the
/// mean diagonal of their Gram matrix: the differences of successive residuals are often
/// nearly dependent, and this keeps the small system solvable while moving the mixing
/// coefficients by about 1e-10 of their size.
pub const ANDERSON_REGULARIZATION: f64 = 1e-10;

// Limits of the settings.

/// Most Anderson memory a setting may ask for: a bound, not a tuned optimum (`auto` uses
/// 5). The history keeps `2 m` vectors of twice the constraint space's dimension and its
/// solve is an `m x m` system each iteration, so the bound caps the memory and the work a
/// setting can ask for.
pub const ANDERSON_MEMORY_MAX: usize = 64;
