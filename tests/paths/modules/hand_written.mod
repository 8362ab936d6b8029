%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE rollerPass
  ! Hand-written: lower-case keywords, robtargets split over lines with comments,
  ! scientific notation, PERS data, LOCAL data and routines, inline targets,
  ! RelTool, an assignment, and several PROCs.
  local pers wobjdata wobjDrum := [ FALSE, TRUE, "",
                                    [ [ 1000, 0, 500 ], [ 1, 0, 0, 0 ] ],   ! uframe: the fixture
                                    [ [ 0, 0, 0 ], [ 0.7071068, 0.7071068, 0, 0 ] ] ]; ! oframe: the drum, +90 deg about x
  pers robtarget pApproach := [ [ 0, 0, 300 ],
                                [ 1, 0, 0, 0 ],     ! tool along the object's -z? no: q = identity
                                [ 0, 0, 0, 0 ],
                                [ 9.0E+09, 9.0E+09, 9.0E+09, 9.0E+09, 9.0E+09, 9.0E+09 ] ];
  LOCAL VAR robtarget pWork;
  CONST num nStep := 2.5e1;   ! mm between passes
  CONST robtarget arc{3} := [
    [[0,0,250],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],
    [[50,0,245],[0.9961947,0,0.0871557,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],
    [[100,0,230],[0.9848078,0,0.1736482,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]] ];

  proc rollerPass()
    moveL pApproach, v100, z10, tool0 \WObj:=wobjDrum;
    pWork := Offs(pApproach, 0, 0, -nStep);
    MoveL pWork, v50, fine, tool0 \WObj:=wobjDrum;
    MoveL arc{1}, v50, z1, tool0 \WObj:=wobjDrum;
    MoveC arc{2}, arc{3}, v50, z1, tool0 \WObj:=wobjDrum;
    MoveL [[100,0,300],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, tool0 \WObj:=wobjDrum;
    MoveL RelTool(arc{3}, 0, 0, -10 \Rx:=10 \Rz:=-20), v100, fine, tool0 \WObj:=wobjDrum;
  ERROR
    MoveL pApproach, v100, fine, tool0 \WObj:=wobjDrum;
  endproc

  LOCAL PROC other()
    MoveL pApproach, v100, fine, tool0;
  ENDPROC
ENDMODULE
