//! What one beam does at its voxel (thesis §4.4.1, §5.5.5–§5.5.6): its fate under each lit rule
//! (the thesis's, the plane rule, exact occluders), the empty-frustum skip, and the split's
//! routing of what goes on (sub-beams to the output buffers or the cell's own FIFO, peeled runs
//! of rays). Each fills a [`Fate`] that the step commits only if everything fits (no loss).

use super::*;

impl<F: FracBits, const FA: usize, const OB: usize, const L: usize> LightCell<F, FA, OB, L> {
    /// Decide a beam's fate into `f` without changing the cell.
    pub(super) fn fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        cell: &Cell<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        f.reset();
        match env.rule {
            LitRule::Thesis => self.thesis_fate(m, &cell.store, env, f),
            LitRule::Plane => self.plane_fate(m, cell, env, f),
            #[cfg(feature = "exact-occluders")]
            LitRule::Exact => self.exact_fate(m, &cell.store, env, f),
        }
    }

    /// The thesis's rule (§5.5.5): an occupied voxel absorbs the beam and is lit by it.
    pub(super) fn thesis_fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        store: &DexelStore<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        if store.occupied(m.z).is_some() {
            f.absorbed = m.beam.ray_count();
            f.lit = true;
            record(&mut f.events, Some(m.z), &m.beam);
            return;
        }
        if self.frustum_skips(m, env, f) {
            return;
        }
        self.route(&m.beam, m.z, env, f, Decide::PLAIN);
    }

    /// The empty-frustum skip ([`LightEnv::frustum`]): drops the beam (its rays skipped) when
    /// none of its rays can meet an occupied block at a later layer. For a beam with nothing to
    /// do at its own voxel.
    pub(super) fn frustum_skips(&self, m: &BeamMsg<F>, env: &LightEnv<'_, F>, f: &mut Fate<'_, F>) -> bool {
        let b = &m.beam;
        let skip = env.frustum.is_some_and(|o| o.frustum_empty(b, env.source, env.far, b.layer().0 + 1));
        if skip {
            f.skipped = b.ray_count();
            record(&mut f.events, None, b);
        }
        skip
    }

    /// The transverse position of voxel `z` of this column for direction `dir`.
    pub(super) fn at(&self, dir: Direction, z: Depth) -> ([i64; 3], Transverse) {
        let pos = [self.x as i64, self.y as i64, z as i64];
        let (ua, va) = dir.transverse();
        (pos, Transverse { u: pos[ua.index()] as i32, v: pos[va.index()] as i32 })
    }

    /// Split `beam` (held at voxel `z` of this column) and file its sub-beams into `f`: `decide`
    /// says, by transverse offset, whether a sub-beam is sent (terminal or not, with what local
    /// state) or absorbed here. Sub-beams leaving the grid count as exited, those the receding
    /// skip drops as skipped; a sub-beam's rays are its rectangle's.
    #[inline]
    pub(super) fn route(&self, beam: &Beam<F>, z: Depth, env: &LightEnv<'_, F>, f: &mut Fate<'_, F>, decide: Decide) {
        self.route_counted(beam, z, env, f, decide, None);
    }

    /// [`LightCell::route`] with, when `fixed` is given, every sub-beam's rays counted as
    /// `(rays, of which terminal at the next layer)` = `fixed` instead of its rectangle's (a
    /// notch removes some: the caller counted them).
    pub(super) fn route_counted(
        &self,
        beam: &Beam<F>,
        z: Depth,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
        decide: Decide,
        fixed: Option<(u64, u64)>,
    ) {
        let rays = |b: &Beam<F>, terminal: bool| {
            fixed.unwrap_or_else(|| (b.ray_count(), if terminal { b.ray_count() } else { 0 }))
        };
        let dir = beam.direction();
        let (pos, at) = self.at(dir, z);
        let Fate { subs, exited, skipped, absorbed, after_empty, after_outside, events, .. } = f;
        let (after_empty, after_outside) = (*after_empty, *after_outside);
        debug_assert_eq!(env.bounds, SubBeamBounds::new(env.n, env.depth, env.skip, env.source));
        let bounds = &env.bounds;
        // The principal step to the next layer: one voxel, but none from layer 0 (the source
        // voxel) when layer 1 is the source voxel's slab (rays from the light, [`Source::slab`]).
        let w = dir.principal().index();
        let step_w = match beam.layer().0 {
            0 if cfg!(feature = "rays-from-light") => {
                (env.source.slab(dir, Layer(1)) - env.source.slab(dir, Layer(0))) as i8
            }
            _ => dir.sign(),
        };
        // At the far plane (k = D) or for a beam that is not this source's: the next layer is
        // outside every grid the far distance was chosen for; the rays leave.
        let Ok(split) = beam.split_axes(env.source, env.far, at) else {
            *exited += rays(beam, false).0;
            record(events, None, beam);
            return;
        };
        // The voxel of the sub-beam with offset (0, 0): one layer on; a sub-beam's offset moves
        // it on the transverse axes.
        let (ua, va) = dir.transverse();
        let (ua, va) = (ua.index(), va.index());
        let mut ahead = pos;
        ahead[w] += step_w as i64;
        split.each(env.order, |offset, i, j| {
            let sb = split.sub_beam(beam, i, j);
            let (terminal, local) = match decide.at(offset) {
                Sub::Send(t, l) => (t, l),
                Sub::Absorb => {
                    *absorbed += rays(&sb, false).0;
                    record(events, Some(z), &sb);
                    return;
                }
            };
            let mut to = ahead;
            to[ua] += offset.du as i64;
            to[va] += offset.dv as i64;
            if bounds.keeps(dir, to) {
                let target = match Port::from_delta((to[0] - pos[0]) as i8, (to[1] - pos[1]) as i8) {
                    Some(p) => Target::Out(p),
                    None => Target::SelfFifo,
                };
                // A ray staying in its column meets the same dexel's plane, or another dexel
                // (the column rule), or an empty voxel next: it carries no outside flag.
                let outside = after_outside && target != Target::SelfFifo;
                let beam = sb.with_terminal(terminal).with_after_empty(after_empty).with_after_outside(outside);
                let msg = BeamMsg { local, ..BeamMsg::new(beam, to[2] as Depth) };
                // At most nine sub-beams: never full.
                let _ = subs.push((target, msg));
            } else if !bounds.in_grid(to) {
                *exited += rays(&sb, terminal).0;
                record(events, None, &sb);
            } else {
                // Dropped by the receding skip; a terminal ray dies at its next voxel anyway
                // (lighting nothing: it is beyond every occupied voxel): absorbed.
                let (all, dying) = rays(&sb, terminal);
                *absorbed += dying;
                *skipped += all - dying;
                record(events, None, &sb);
            }
        });
    }

    /// The plane rule ([`crate::lit`]) at this beam's voxel.
    pub(super) fn plane_fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        cell: &Cell<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let b = &m.beam;
        let dir = b.direction();
        let k = b.layer().0 as i64;
        let (x, y) = (self.x as i64, self.y as i64);
        let plane = |d: &Dexel| RayPlane::new(&d.plane, [x, y, d.span.lo as i64], env.source, dir, env.far);
        let own = cell.store.occupied(m.z);
        let notch = m.local.notch();
        let state = notch.and_then(|n| cell.store.occupied(n.state).map(|d| (plane(d), n)));
        let other = matches!((notch, own), (Some(n), Some(d)) if !d.span.contains(n.state));
        let visible = cell
            .visible
            .filter(|v| v.brackets(m.z as i64))
            .map(|v| RayPlane::new(&v.plane, [x, y, v.z_v as i64], env.source, dir, env.far));
        let mut visit = Visit::new(k, Arrival::of(b), own.map(plane), state, visible, other);
        f.after_empty = own.is_none();
        f.after_outside = false;
        if visit.is_plain() {
            // Nothing happens at this voxel: the thesis's path (a notched beam is not plain).
            if m.local == Local::NONE && self.frustum_skips(m, env, f) {
                return;
            }
            self.route(b, m.z, env, f, Decide::PLAIN);
            return;
        }
        let stay = self.staying(b, env);
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        if let Some(bits) = uniform(&visit.tests, u, v) {
            let out = visit.verdict(bits, false);
            let stays = visit.verdict(bits, true);
            f.after_outside = visit.outside(bits);
            f.lit = out.lit;
            f.visible = out.visible;
            match out.out {
                Out::Absent => {}
                Out::Absorbed => f.absorbed = b.ray_count(),
                Out::Continue | Out::Terminal => {
                    let send = out.out == Out::Terminal;
                    let stay_sub = match stays.out {
                        Out::Continue => Sub::Send(false, self.carried(m, own.map(|d| d.span), k, &visit)),
                        Out::Terminal => Sub::Send(true, Local::NONE),
                        _ => Sub::Absorb,
                    };
                    let decide = Decide { other: Sub::Send(send, Local::NONE), stay: stay.map(|_| stay_sub) };
                    self.route(b, m.z, env, f, decide);
                }
            }
            return;
        }
        let carry = self.carried(m, own.map(|d| d.span), k, &visit);
        self.peel::<_, { 2 * crate::lit::MAX_TESTS + 1 }>(m, &mut visit, &|_, _| {}, stay, carry, env, f);
    }

    /// The exact-occluder rule ([`crate::occluder::ExactVisit`]) at this beam's voxel.
    #[cfg(feature = "exact-occluders")]
    pub(super) fn exact_fate<const D: usize>(
        &self,
        m: &BeamMsg<F>,
        store: &DexelStore<D>,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let b = &m.beam;
        let dir = b.direction();
        let k = b.layer().0 as i64;
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        let column = env.occluders.map(|o| o.column(self.x, self.y, m.z));
        let triangles = column.map_or(&[][..], |c| c.triangles);
        let notch = m.local.notch().map(|n| n.t1 as i64);
        // The triangles that may cut a plain beam past layer 1, when the host knows them
        // ([`crate::occluder::near_voxels`]); otherwise every one.
        let candidates = match (column, notch, k >= 2) {
            (Some(c), None, true) => c.candidates(m.z),
            _ => ALL_CANDIDATES,
        };
        let mut tests = ExactTests::new();
        let mut visit = ExactVisit::new(
            &mut tests,
            triangles,
            column.and_then(|c| c.seen),
            candidates,
            env.source,
            dir,
            env.far,
            k,
            (u, v),
            b.is_terminal(),
            notch,
        );
        f.per_ray = visit.per_ray();
        // The lit-ray ratio: the candidates this beam brings to the column's target voxel
        // ([`crate::visibility`]); those of a rectangle the step keeps are taken back below.
        #[cfg(feature = "lit-ray-ratio")]
        let counted = column.and_then(|c| c.voxel).filter(|tv| tv.receives(b));
        #[cfg(feature = "lit-ray-ratio")]
        if let Some(tv) = counted {
            f.arrived += tv.count::<_, EXACT_SEGMENTS>(&visit, u, v);
        }
        // The receiver: the column's target ray, if this beam brings it here (absent rays were
        // absorbed earlier; a terminal or absorbed one still arrived).
        let target = column.and_then(|c| c.target);
        if let Some(t) = target.filter(|t| t.in_beam(b)) {
            // It arrived, and no triangle of this column or its neighbours shadows the pixel
            // from close by.
            let lit = visit.verdict(visit.bits(t.a, t.b), false).out.present() && !t.in_contact_shadow(triangles);
            f.visible = lit;
            f.lit = lit;
        }
        // The full lit store keeps every occupied voxel whose own ray arrives
        // ([`crate::receiver::voxel_ray`]); the visible-only store, the pixel's target voxel.
        if !env.lit_visible_only {
            f.lit = store.occupied(m.z).is_some()
                && crate::receiver::voxel_ray(self.x as i32, self.y as i32, m.z as i64, env.source, env.far)
                    .is_some_and(|t| t.in_beam(b) && visit.verdict(visit.bits(t.a, t.b), false).out.present());
        }
        if visit.is_plain() {
            if m.local == Local::NONE && !f.visible && self.frustum_skips(m, env, f) {
                return;
            }
            self.route(b, m.z, env, f, Decide::PLAIN);
            return;
        }
        let stay = self.staying(b, env);
        // Staying rays carry the notch of this column's triangles since they entered it, unless
        // every ray of the rectangle had the same verdict (then none is missing).
        let carry = match (visit.is_uniform(), notch) {
            (true, _) => Local::NONE,
            (false, t1) => Local::notched(Notch {
                state: 0,
                t1: t1.unwrap_or((k - 1).max(0)) as u16,
                t2: k as u16,
                fresh: false,
                front: false,
            }),
        };
        if visit.is_uniform() {
            let out = visit.verdict(0, false);
            let stays = visit.verdict(0, true);
            match out.out {
                Out::Absent => {}
                Out::Absorbed => f.absorbed = b.ray_count(),
                Out::Continue | Out::Terminal => {
                    let send = out.out == Out::Terminal;
                    let stay_sub = Sub::Send(stays.out == Out::Terminal, carry);
                    let decide = Decide { other: Sub::Send(send, Local::NONE), stay: stay.map(|_| stay_sub) };
                    self.route(b, m.z, env, f, decide);
                }
            }
            return;
        }
        let revisit =
            |b: &Beam<F>, v: &mut ExactVisit<'_, '_, F>| v.rejudge((lattice(b.u()), lattice(b.v())), b.is_terminal());
        self.peel::<_, EXACT_SEGMENTS>(m, &mut visit, &revisit, stay, carry, env, f);
        // The kept rest is counted by the step that takes it (the visit holds for it: peeling
        // took it again on what it keeps).
        #[cfg(feature = "lit-ray-ratio")]
        if let (Some(tv), Some(rest)) = (counted, f.keep) {
            f.arrived -= tv.count::<_, EXACT_SEGMENTS>(&visit, lattice(rest.beam.u()), lattice(rest.beam.v()));
        }
    }

    /// The local state a ±z beam's staying rays carry to the next layer of this column (see
    /// the column rule of [`crate::lit`]): after a surface voxel (`own`: its dexel's span; the
    /// staying rays were not absorbed by the column rule), a fresh notch of that dexel's plane
    /// (extending the beam's own when it is the same dexel); after an empty voxel, the beam's
    /// notch without its terminal rays, which died there.
    pub(super) fn carried(&self, m: &BeamMsg<F>, own: Option<crate::units::Span>, k: i64, visit: &Visit) -> Local {
        let notch = m.local.notch();
        match own {
            Some(span) => {
                // A new notch excludes, besides the rays that crossed, those the visit absorbed
                // for arriving behind the plane (rule 4).
                let (t1, front) = match notch {
                    Some(n) if span.contains(n.state) => (n.t1, n.front),
                    _ => ((k - 1).max(0) as u16, visit.absorbs_behind()),
                };
                Local::notched(Notch { state: m.z, t1, t2: k as u16, fresh: true, front })
            }
            None => match notch {
                Some(n) => Local::notched(Notch { t2: n.t2 + n.fresh as u16, fresh: false, ..n }),
                None => Local::NONE,
            },
        }
    }

    /// The rays an entry holds: its rectangle's, less those its notch excludes (counted run by
    /// run, [`crate::lit`]). For the per-step conservation check of debug builds.
    #[cfg(debug_assertions)]
    pub(super) fn present_rays<const D: usize>(&self, m: &BeamMsg<F>, cell: &Cell<D>, env: &LightEnv<'_, F>) -> u64 {
        let b = &m.beam;
        let Some(n) = m.local.notch() else {
            return b.ray_count();
        };
        let (u, v) = (lattice(b.u()), lattice(b.v()));
        let (dir, k) = (b.direction(), b.layer().0 as i64);
        #[cfg(feature = "exact-occluders")]
        if env.rule.is_exact() {
            let triangles = env.occluders.map_or(&[][..], |o| o.triangles(self.x, self.y));
            let seen = env.occluders.and_then(|o| o.seen(self.x, self.y));
            let mut tests = ExactTests::new();
            let visit = ExactVisit::new(
                &mut tests,
                triangles,
                seen,
                ALL_CANDIDATES,
                env.source,
                dir,
                env.far,
                k,
                (u, v),
                false,
                Some(n.t1 as i64),
            );
            return Self::count_present::<_, EXACT_SEGMENTS>(&visit, u, v);
        }
        let Some(d) = cell.store.occupied(n.state) else {
            return b.ray_count();
        };
        let (x, y) = (self.x as i64, self.y as i64);
        let plane = RayPlane::new(&d.plane, [x, y, d.span.lo as i64], env.source, dir, env.far);
        let visit = Visit::new(k, Arrival::NONE, None, Some((plane, Notch { fresh: false, ..n })), None, false);
        Self::count_present::<_, { 2 * crate::lit::MAX_TESTS + 1 }>(&visit, u, v)
    }

    /// The rays of rectangle `u × v` that `visit` finds present (not cut out by a notch).
    #[cfg(debug_assertions)]
    pub(super) fn count_present<R: Rule, const C: usize>(visit: &R, u: (i64, i64), v: (i64, i64)) -> u64 {
        let mut seg = Segments::<C>::new();
        let (mut line, mut present) = (u.0, 0u64);
        while line <= u.1 {
            let end = visit.run_end(Along::V, line, u.1, v.0, v.1);
            visit.line(Along::V, line, v.0, v.1, &mut seg);
            for (start, stop, bits) in spans(&seg, v.1) {
                if visit.verdict(bits, false).out.present() {
                    present += (end - line + 1) as u64 * (stop - start + 1) as u64;
                }
            }
            line = end + 1;
        }
        present
    }

    /// For a ±z beam, the lattice rays of each axis that stay in this column at the next layer
    /// (`None` for the other directions, whose sub-beams all change column, and at the far plane
    /// k = D, past which every ray leaves).
    pub(super) fn staying(&self, b: &Beam<F>, env: &LightEnv<'_, F>) -> Option<((i64, i64), (i64, i64))> {
        let dir = b.direction();
        if dir.principal() != crate::beam::Axis::Z || b.layer().0 >= env.far.get() {
            return None;
        }
        let (ua, va) = dir.transverse();
        let reach = env.source.reach(dir, Layer(b.layer().0 + 1));
        let su = staying_rays(env.source.pos[ua.index()], self.x as i32, env.far, reach);
        let sv = staying_rays(env.source.pos[va.index()], self.y as i32, env.far, reach);
        Some((su, sv))
    }

    /// Peel a beam whose rectangle is not uniform under the plane rule: one rectangle of uniform
    /// verdict per step, the rest staying in the FIFO slot (see [`crate::lit`]). The rays that
    /// change column go first, run by run, from the outside in (for a ±z beam: the columns
    /// before and after the staying rays, then the rows below and above them), so that what is
    /// left is always a rectangle; the staying rays go last, as one beam, and the entry is
    /// consumed.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn peel<R: Rule, const C: usize>(
        &self,
        m: &BeamMsg<F>,
        visit: &mut R,
        revisit: &dyn Fn(&Beam<F>, &mut R),
        stay: Option<((i64, i64), (i64, i64))>,
        carry: Local,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let mut beam = m.beam;
        let mut piece = m.local.piece;
        let mut seg = Segments::<C>::new();
        loop {
            let (a0, a1) = lattice(beam.u());
            let (b0, b1) = lattice(beam.v());
            // The region of this step: lines `from` toward `to` along `along` (upward: from the
            // low end), across `cross`.
            let region = match stay {
                Some(((su0, su1), (sv0, sv1))) => {
                    if a0 < su0 {
                        Some((Along::V, true, a0, a1.min(su0 - 1), (b0, b1)))
                    } else if a1 > su1 {
                        Some((Along::V, false, a1, a0.max(su1 + 1), (b0, b1)))
                    } else if b0 < sv0 {
                        Some((Along::U, true, b0, b1.min(sv0 - 1), (a0, a1)))
                    } else if b1 > sv1 {
                        Some((Along::U, false, b1, b0.max(sv1 + 1), (a0, a1)))
                    } else {
                        None
                    }
                }
                None => Some((Along::V, true, a0, a1, (b0, b1))),
            };
            let Some((along, upward, from, to, cross)) = region else {
                // Only staying rays are left: one beam to this column's next voxel.
                self.peel_staying::<R, C>(m, beam, visit, carry, env, f);
                return;
            };
            visit.line(along, from, cross.0, cross.1, &mut seg);
            let end = if R::BY_VERDICT {
                let mut next = Segments::<C>::new();
                crate::lit::verdict_run_end(&*visit, along, (from, to), cross, &seg, &mut next)
            } else {
                visit.run_end(along, from, to, cross.0, cross.1)
            };
            let lines = (from.min(end), from.max(end));

            let width = (lines.1 - lines.0 + 1) as u64;
            let (mut present, mut sent, mut count) = (0u64, 0u64, 0u8);
            let mut emit = None;
            let mut pieces = |(start, stop, v, outside): (i64, i64, Verdict, bool)| {
                f.lit |= v.lit;
                f.visible |= v.visible;
                let rays = width * (stop - start + 1) as u64;
                if v.out.present() {
                    present += rays;
                }
                if v.out.goes_on() {
                    if count == piece {
                        emit = Some((start, stop, v.out == Out::Terminal, outside));
                    }
                    count += 1;
                    sent += rays;
                }
            };
            if R::BY_VERDICT {
                crate::lit::verdict_spans(&*visit, &seg, cross.1, false).for_each(&mut pieces);
            } else {
                spans(&seg, cross.1)
                    .for_each(|(a, b, bits)| pieces((a, b, visit.verdict(bits, false), visit.outside(bits))));
            }
            if let Some((start, stop, terminal, outside)) = emit {
                let (u, v) = match along {
                    Along::V => (lines, (start, stop)),
                    Along::U => ((start, stop), lines),
                };
                let rect = beam.with_rays(range::<F>(u), range::<F>(v));
                f.after_outside = outside;
                self.route(&rect, m.z, env, f, Decide::all(Sub::Send(terminal, Local::NONE)));
                piece += 1;
                if piece < count {
                    f.keep = Some(BeamMsg { beam, local: Local { piece, ..m.local }, ..*m });
                    return;
                }
            }
            // The run is done: its rays not sent were absorbed; the beam shrinks past it.
            f.absorbed += present - sent;
            piece = 0;
            let (u, v) = (lattice(beam.u()), lattice(beam.v()));
            let shrunk = match (along, upward) {
                (Along::V, true) => ((lines.1 + 1, u.1), v),
                (Along::V, false) => ((u.0, lines.0 - 1), v),
                (Along::U, true) => (u, (lines.1 + 1, v.1)),
                (Along::U, false) => (u, (v.0, lines.0 - 1)),
            };
            if shrunk.0 .0 > shrunk.0 .1 || shrunk.1 .0 > shrunk.1 .1 {
                // Nothing left: the entry is consumed.
                return;
            }
            beam = beam.with_rays(range::<F>(shrunk.0), range::<F>(shrunk.1));
            // A visit that depends on the rectangle is taken again on what is left: the same
            // visit the next step will take on it, so a run's pieces are cut alike in every step.
            revisit(&beam, visit);
            if emit.is_some() {
                f.keep = Some(BeamMsg { beam, local: Local { piece: 0, ..m.local }, ..*m });
                return;
            }
        }
    }

    /// The last step of a peeled ±z beam: `beam` holds only rays that stay in the column. Those
    /// that go on become one beam for the next voxel of the column ([`LightCell::carried`]); the
    /// entry is consumed.
    pub(super) fn peel_staying<R: Rule, const C: usize>(
        &self,
        m: &BeamMsg<F>,
        beam: Beam<F>,
        visit: &R,
        carry: Local,
        env: &LightEnv<'_, F>,
        f: &mut Fate<'_, F>,
    ) {
        let (u, v) = (lattice(beam.u()), lattice(beam.v()));
        let (mut present, mut going, mut dying) = (0u64, 0u64, 0u64);
        let mut seg = Segments::<C>::new();
        let mut line = u.0;
        while line <= u.1 {
            let end = visit.run_end(Along::V, line, u.1, v.0, v.1);
            let width = (end - line + 1) as u64;
            visit.line(Along::V, line, v.0, v.1, &mut seg);
            for (start, stop, bits) in spans(&seg, v.1) {
                let verdict = visit.verdict(bits, true);
                f.lit |= verdict.lit;
                f.visible |= verdict.visible;
                let rays = width * (stop - start + 1) as u64;
                if verdict.out.present() {
                    present += rays;
                }
                if verdict.out.goes_on() {
                    going += rays;
                }
                if verdict.out == Out::Terminal {
                    dying += rays;
                }
            }
            line = end + 1;
        }
        f.absorbed += present - going;
        if going > 0 {
            self.route_counted(&beam, m.z, env, f, Decide::all(Sub::Send(false, carry)), Some((going, dying)));
        }
    }
}
