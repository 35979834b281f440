C     Isotropic linear elasticity as an Abaqus UMAT, in fixed-form
C     Fortran 77 as such subroutines are usually written: the test
C     suite's reference for the UMAT adapter. PROPS(1) = Young's
C     modulus, PROPS(2) = Poisson's ratio. The stress is updated with the
C     strain increment, STRESS = STRESS + DDSDDE DSTRAN, in Abaqus'
C     component order 11, 22, 33, 12, 13, 23 with engineering shears.
      SUBROUTINE UMAT(STRESS,STATEV,DDSDDE,SSE,SPD,SCD,
     1 RPL,DDSDDT,DRPLDE,DRPLDT,
     2 STRAN,DSTRAN,TIME,DTIME,TEMP,DTEMP,PREDEF,DPRED,CMNAME,
     3 NDI,NSHR,NTENS,NSTATV,PROPS,NPROPS,COORDS,DROT,PNEWDT,
     4 CELENT,DFGRD0,DFGRD1,NOEL,NPT,LAYER,KSPT,KSTEP,KINC)
      IMPLICIT NONE
      CHARACTER*80 CMNAME
      INTEGER NDI,NSHR,NTENS,NSTATV,NPROPS,NOEL,NPT,LAYER,KSPT,
     1 KSTEP,KINC
      DOUBLE PRECISION STRESS(NTENS),STATEV(*),DDSDDE(NTENS,NTENS),
     1 SSE,SPD,SCD,RPL,DDSDDT(NTENS),DRPLDE(NTENS),DRPLDT,
     2 STRAN(NTENS),DSTRAN(NTENS),TIME(2),DTIME,TEMP,DTEMP,
     3 PREDEF(1),DPRED(1),PROPS(NPROPS),COORDS(3),DROT(3,3),PNEWDT,
     4 CELENT,DFGRD0(3,3),DFGRD1(3,3)
      DOUBLE PRECISION E,ANU,G,ALAM
      INTEGER I,J
      E = PROPS(1)
      ANU = PROPS(2)
      G = E/(2.D0*(1.D0+ANU))
      ALAM = E*ANU/((1.D0+ANU)*(1.D0-2.D0*ANU))
      DO I = 1,NTENS
        DO J = 1,NTENS
          DDSDDE(I,J) = 0.D0
        END DO
      END DO
      DO I = 1,NDI
        DO J = 1,NDI
          DDSDDE(I,J) = ALAM
        END DO
        DDSDDE(I,I) = ALAM + 2.D0*G
      END DO
      DO I = NDI+1,NTENS
        DDSDDE(I,I) = G
      END DO
      DO I = 1,NTENS
        DO J = 1,NTENS
          STRESS(I) = STRESS(I) + DDSDDE(I,J)*DSTRAN(J)
        END DO
      END DO
      RETURN
      END
